"""Solvers: advance a :class:`~dftl_warp.state.State` by substeps of length ``dt`` (s).

:class:`DFTLSolver` implements Dynamic Follow-The-Leader (Mueller, Kim, Chentanez 2012) with the
velocity correction in the paper's *posterior* form or the seed's *prior* form (the default, whose
velocities are physical). ``solver="ftl"`` is the same sweep without correction (damping 0).
:func:`make_solver` picks a solver by name.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import warp as wp

from .kernels.diagnostics import strand_diagnostics_kernel
from .kernels.ftl import CORRECTIONS, step_kernel
from .kernels.fused import fused_block_dim, fused_step_kernel
from .kernels.pipelined import CUDA_LANES, pipelined_kernel, pipelined_serial_kernel

SOLVERS = ("dftl", "ftl", "pbd", "reference")

#: longest strand (vertices) the fused-substep kernels keep on chip (posterior form)
MAX_FUSED_VERTICES = 64

#: longest strand (vertices) the prior form keeps on chip; longer strands take the pipelined
#: kernel (:mod:`dftl_warp.kernels.pipelined`, any length), measured faster there on the H200
ON_CHIP_PRIOR_VERTICES = 32

#: threads per block of the pipelined CUDA kernel
PIPELINED_BLOCK = 128

#: standard gravity, m/s^2, along -Y (the default up axis)
DEFAULT_GRAVITY = (0.0, -9.81, 0.0)


class DFTLSolver:
    """Dynamic Follow-The-Leader.

    Args:
        model: the :class:`~dftl_warp.model.Model` to simulate.
        damping: ``s`` in [0, 1], the share of the follow-the-leader correction removed from the
            velocity (1: the seed's physically convergent choice).
        correction: ``"prior"`` (seed eq. 4-6) or ``"posterior"`` (paper eq. 1-3).
        gravity: acceleration (3,), m/s^2 (stage units/s^2 for USD scenes).
        fused: run a frame's substeps in one launch per strand group, state kept on chip
            (:mod:`dftl_warp.kernels.fused`; identical results). ``None``: on CUDA, for the frames
            where the H200 measurements say it is faster (:func:`fused_pays`).
    """

    name = "dftl"

    def __init__(self, model, *, damping: float = 1.0, correction: str = "prior", gravity=DEFAULT_GRAVITY,
                 fused: bool | None = None):
        if correction not in CORRECTIONS:
            raise ValueError(f"unknown correction {correction!r}; choose prior or posterior")
        if not (0.0 <= float(damping) <= 1.0):
            raise ValueError(f"damping must be in [0, 1], got {damping}")
        self.model = model
        self.damping = float(damping)
        self.correction = correction
        self.gravity = model.vec3(*np.asarray(gravity, dtype=np.float64).reshape(3))
        # the step specialized to the model's features; a gravity-only model gets the bare kernel
        self._kernel = step_kernel(model.scalar, correction, model.feature_flags)
        self._features = None
        if model.feature_flags:
            from .feature_data import FeatureStep

            self._features = FeatureStep(model, self._kernel)
        self._graphs: dict = {}
        # the prior form fuses strands of any length (the pipelined kernel); the posterior form
        # keeps whole strands on chip
        fits = (correction == "prior" or model.num_strands == 0
                or int(model.layout.strand_count.max()) <= MAX_FUSED_VERTICES)
        if fused and not fits:
            raise ValueError(f"fused substeps in the posterior form need strands of at most {MAX_FUSED_VERTICES} "
                             "vertices (the prior form has no limit)")
        # the fused kernels are the bare step; a scene with features steps substep by substep
        if fused and self._features is not None:
            raise ValueError("fused substeps run the bare step only; this model has features "
                             f"({', '.join(sorted(model.feature_flags))})")
        fits = fits and self._features is None
        self.fused = bool(model.device.is_cuda and fits) if fused is None else bool(fused)
        #: choose per frame with fused_pays (only when the caller left ``fused`` to us)
        self._fused_auto = fused is None
        self._longest = int(model.layout.strand_count.max()) if model.num_strands else 0
        # strands kept on chip, by capacity; longer ones (prior form) pipelined, by vertex count
        on_chip = ON_CHIP_PRIOR_VERTICES if correction == "prior" else MAX_FUSED_VERTICES
        self._fused_runs = (fused_runs(model.layout.strand_count, model.scalar, correction, longest=on_chip)
                            if self.fused else [])
        self._fused_block_dims = [fused_block_dim(model.scalar, fused_capacity(model.layout.strand_count[first]))
                                  for _, first, _ in self._fused_runs]
        self._pipelined_runs = pipelined_runs(model.layout, on_chip) if self.fused else []
        self._lane_scratch: dict = {}

    @property
    def carries_corrections(self) -> bool:
        return self.correction == "prior"

    def state(self):
        """A rest State with exactly the arrays this solver needs."""
        return self.model.state(with_corrections=self.carries_corrections)

    def step(self, state_in, state_out, control, dt: float, root_alpha: float = 1.0) -> None:
        """Advance ``state_in`` by ``dt`` seconds into ``state_out`` (which may be ``state_in``).

        Roots are placed at ``control``'s targets interpolated by ``root_alpha`` in [0, 1].
        """
        m = self.model
        if self.carries_corrections and (state_in.corrections is None or state_out.corrections is None):
            raise ValueError("the prior correction form needs states with corrections (solver.state())")
        if self._features is not None:
            self._features.launch(state_in, state_out, control, dt, root_alpha,
                                  self.feature_head(control, dt, root_alpha))
            return
        inputs = [
            m.strand_base, m.strand_stride, m.strand_count,
            control.root_start, control.root_end, root_alpha,
            m.rest_lengths, self.gravity, dt, self.damping,
            state_in.positions, state_in.velocities,
        ]
        outputs = [state_out.positions, state_out.velocities]
        if self.carries_corrections:
            if state_in.corrections is None or state_out.corrections is None:
                raise ValueError("the prior correction form needs states with corrections (solver.state())")
            inputs.append(state_in.corrections)
            outputs.append(state_out.corrections)
        wp.launch(self._kernel, dim=m.num_strands, inputs=inputs, outputs=outputs, device=m.device)

    def feature_head(self, control, dt: float, root_alpha: float) -> list:
        """The leading inputs of the featured sweep (:meth:`FeatureStep.sweep
        <dftl_warp.feature_data.FeatureStep.sweep>`)."""
        m = self.model
        return [m.strand_base, m.strand_stride, m.strand_count, control.root_start, control.root_end,
                root_alpha, m.rest_lengths, self.gravity, dt, self.damping]

    def advance(self, state, control, dt: float, substeps: int) -> None:
        """``substeps`` steps of ``dt`` in place, roots moving linearly across them.

        On CUDA the substeps are captured once in a CUDA graph and replayed afterwards.
        """
        m = self.model
        if m.num_strands == 0:
            return

        use_fused = self.fused and (not self._fused_auto or fused_pays(self._longest, substeps, m.precision, self.correction))
        if self._pipelined_runs and m.device.is_cuda and substeps not in CUDA_LANES:
            use_fused = False  # the CUDA pipeline has one lane per substep, a divisor of the warp

        def run():
            if use_fused:
                self._launch_fused(state, control, dt, substeps)
                return
            real = np.dtype(m.precision).type  # alpha rounded as the fused kernels compute it
            for k in range(substeps):
                self.step(state, state, control, dt, float(real(k + 1) / real(substeps)))

        if not m.device.is_cuda:
            run()
            return
        key = (id(state), id(control), float(dt), int(substeps))
        graph = self._graphs.get(key)
        if graph is None:
            kernels = self._features.kernels() if self._features is not None else [self._kernel]
            kernels = kernels + [run[0] for run in self._fused_runs]
            if use_fused and self._pipelined_runs:
                kernels.append(pipelined_kernel(m.scalar, substeps))
            for kernel in kernels:
                kernel.module.load(m.device)  # compile before capturing
            with wp.ScopedCapture(device=m.device) as capture:
                run()
            graph = self._graphs[key] = capture.graph
        wp.capture_launch(graph)

    def _launch_fused(self, state, control, dt, substeps):
        m = self.model
        if self.carries_corrections and state.corrections is None:
            raise ValueError("the prior correction form needs states with corrections (solver.state())")
        for (kernel, first, size), block_dim in zip(self._fused_runs, self._fused_block_dims):
            wp.launch(
                kernel,
                dim=size,
                block_dim=block_dim,
                inputs=[first, m.strand_base, m.strand_stride, m.strand_count, control.root_start,
                        control.root_end, m.rest_lengths, self.gravity, dt, self.damping, substeps,
                        state.positions, state.velocities, state.corrections],
                device=m.device,
            )
        for run in self._pipelined_runs:
            head = [run.first, run.strands, run.groups, run.count, run.base, run.strand_step, run.chunk, run.stride,
                    control.root_start, control.root_end, m.rest_lengths, self.gravity, dt, self.damping]
            tail = [state.positions, state.velocities, state.corrections]
            if m.device.is_cuda:
                wp.launch(pipelined_kernel(m.scalar, substeps), dim=run.groups * substeps, block_dim=PIPELINED_BLOCK,
                          inputs=head + tail, device=m.device)
            else:
                vectors, scalars = self._lanes(run.groups * substeps)
                wp.launch(pipelined_serial_kernel(m.scalar), dim=run.groups,
                          inputs=head + [substeps, vectors, scalars] + tail, device=m.device)

    def _lanes(self, rows: int):
        """Scratch lane states of the serial pipelined kernel (at least ``rows`` lanes)."""
        m = self.model
        if self._lane_scratch.get("rows", 0) < rows:
            self._lane_scratch = {"rows": rows,
                                  "vectors": wp.empty((rows, 6), dtype=m.vec3, device=m.device),
                                  "scalars": wp.empty((rows, 2), dtype=m.scalar, device=m.device)}
        return self._lane_scratch["vectors"], self._lane_scratch["scalars"]

    def diagnostics(self, state) -> dict:
        """Total energy per unit particle mass (J/kg), max relative stretch, max speed (m/s)."""
        m = self.model
        n = m.num_strands
        if n == 0:
            return {"energy": 0.0, "max_stretch": 0.0, "max_speed": 0.0}
        out = [wp.zeros(n, dtype=wp.float64, device=m.device) for _ in range(3)]
        wp.launch(
            strand_diagnostics_kernel(m.scalar),
            dim=n,
            inputs=[m.strand_base, m.strand_stride, m.strand_count, m.rest_lengths, self.gravity,
                    state.positions, state.velocities],
            outputs=out,
            device=m.device,
        )
        energy, stretch, speed = (a.numpy() for a in out)
        # potential energy is measured from the device origin; shift it back to world space
        g = np.array(self.gravity, dtype=np.float64)
        free = float(np.sum(np.maximum(m.counts - 1, 0)))
        return {
            "energy": float(energy.sum() - free * g @ m.origin),
            "max_stretch": float(stretch.max()),
            "max_speed": float(speed.max()),
        }


def fused_pays(longest: int, substeps: int, precision: str, correction: str = "prior") -> bool:
    """Whether fused substeps beat one launch per substep for strands of at most ``longest``
    vertices, from the H200 measurements in docs/benchmarks.md (x the per-step kernel): float32
    strands of up to 32 vertices gain from 2 substeps per frame on (32 vertices: x1.65 at 2, x2.9
    at 4, x4.6 at 8; posterior x1.7 at 2); float64 strands of up to 32 vertices from 4 (x0.69 at
    2, x1.07 at 4, x1.26 at 8). One substep gains little or loses (x0.64-0.99).
    Longer strands in the prior form take the pipelined kernel, which gains from 2 substeps on
    (64 and 128 vertices: x1.3-1.4 at 2, x2.6-2.8 at 8; float64 at 64: x1.7 at 2, x2.7 at 8);
    longer posterior-form strands spill registers and do not gain."""
    if precision == "float32" and longest <= 32:
        return substeps >= 2
    if longest <= 32:
        return substeps >= 4
    return correction == "prior" and substeps >= PIPELINED_PAYS


#: substeps per frame from which the pipelined kernel beats one launch per substep (H200)
PIPELINED_PAYS = 2


def fused_capacity(count: int) -> int:
    """Capacity of the fused kernel serving strands of ``count`` vertices: a multiple of 8, so
    that few kernels serve grooms of many lengths."""
    return int(max(8, -(-int(count) // 8) * 8))


def fused_runs(strand_count, scalar, correction, longest: int = MAX_FUSED_VERTICES):
    """(kernel, first device strand, number of strands) for each run of consecutive device
    strands that share a fused kernel: its capacity, and whether they fill it exactly. Strands
    of more than ``longest`` vertices are left out (pipelined, :func:`pipelined_runs`)."""
    keys = [(fused_capacity(c), bool(fused_capacity(c) == c)) if c <= longest else None for c in strand_count]
    runs, first = [], 0
    for s in range(1, len(keys) + 1):
        if s == len(keys) or keys[s] != keys[first]:
            if keys[first] is not None:
                runs.append((fused_step_kernel(scalar, correction, *keys[first]), first, s - first))
            first = s
    return runs


@dataclass(frozen=True)
class PipelinedRun:
    """Strands ``first ... first + strands - 1`` (device order) of ``count`` vertices each, whose
    particle ``i`` of strand ``first + r`` lives at
    ``base + ((r // 32) * chunk + r % 32) * strand_step + i * stride``, streamed by ``groups`` lane
    groups (:mod:`dftl_warp.kernels.pipelined`). ``chunk`` is 32 unless the layout interleaves."""

    first: int
    strands: int
    count: int
    base: int
    strand_step: int
    stride: int
    groups: int
    chunk: int = 32


def pipelined_runs(layout, longer_than: int) -> list[PipelinedRun]:
    """The runs of strands of more than ``longer_than`` vertices, one per layout group."""
    runs = []
    for count, first, size in layout.groups:
        if count <= longer_than:
            continue
        base = layout.strand_base[first:first + size]
        step = int(base[1] - base[0]) if size > 1 else 0
        stride = layout.strand_stride[first:first + size]
        chunk = layout.chunk_slots
        r = np.arange(size)
        if not (np.array_equal(base, base[0] + step * ((r // 32) * chunk + r % 32)) and (stride == stride[0]).all()):
            raise ValueError(f"layout {layout.name!r}: strands {first}..{first + size - 1} are not evenly spaced")
        # streams of a few hundred particles: fill and drain (2 substeps - 1 sweeps) stay small
        per_group = max(2, 256 // int(count))
        runs.append(PipelinedRun(first=int(first), strands=int(size), count=int(count), base=int(base[0]),
                                 strand_step=step, stride=int(stride[0]), groups=-(-int(size) // per_group),
                                 chunk=chunk))
    return runs


def carries_corrections(solver: str, correction: str) -> bool:
    """Whether the solver named ``solver`` keeps the prior form's corrections in its States."""
    return solver in ("dftl", "ftl") and correction == "prior"


def make_solver(model, solver: str = "dftl", **options):
    """Solver by name: ``"dftl"``, ``"ftl"`` (DFTL with damping 0), ``"pbd"`` (option
    ``iterations``, :class:`~dftl_warp.pbd.PBDSolver`) or ``"reference"``
    (:class:`~dftl_warp.reference.ReferenceSolver`). ``damping`` and ``correction`` do not apply
    to pbd and reference and are ignored there; ``iterations`` applies to pbd only."""
    if solver in ("pbd", "reference"):
        options.pop("damping", None)
        options.pop("correction", None)
        if solver == "pbd":
            from .pbd import PBDSolver

            return PBDSolver(model, **options)
        options.pop("iterations", None)
        from .reference import ReferenceSolver

        return ReferenceSolver(model, **options)
    options.pop("iterations", None)
    if solver == "dftl":
        return DFTLSolver(model, **options)
    if solver == "ftl":
        options["damping"] = 0.0
        return DFTLSolver(model, **options)
    raise ValueError(f"unknown solver {solver!r}; choose one of {', '.join(SOLVERS)}")
