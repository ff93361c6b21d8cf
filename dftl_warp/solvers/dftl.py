"""Solvers: advance a :class:`~dftl_warp.core.state.State` by substeps of length ``dt`` (s).

:class:`DFTLSolver` implements Dynamic Follow-The-Leader (Mueller, Kim, Chentanez 2012) with the
velocity correction in the paper's *posterior* form or the seed's *prior* form (the default, whose
velocities are physical). ``solver="ftl"`` is the same sweep without correction (damping 0).
:func:`make_solver` picks a solver by name.
"""

from __future__ import annotations

from dataclasses import dataclass

import warp as wp

from ..kernels.solvers.ftl import CORRECTIONS
from ..kernels.solvers.fused import fused_block_dim
from ..kernels.solvers.pipelined import CUDA_LANES, pipelined_kernel, pipelined_serial_kernel
from ..kernels.solvers.step import step_kernel
from .base import DEFAULT_GRAVITY, Solver, check_bool, check_damping, register
from .fused_runs import (  # noqa: F401  (re-exported: the fused launch geometry)
    MAX_FUSED_VERTICES,
    ON_CHIP_PRIOR_VERTICES,
    PIPELINED_BLOCK,
    PIPELINED_PAYS,
    fused_capacity,
    fused_pays,
    fused_runs,
    pipelined_runs,
)

@register
class DFTLSolver(Solver):
    """Dynamic Follow-The-Leader.

    Args:
        model: the :class:`~dftl_warp.core.model.Model` to simulate.
        damping: ``s`` in [0, 1], the share of the follow-the-leader correction removed from the
            velocity (1: the seed's physically convergent choice).
        correction: ``"prior"`` (seed eq. 4-6) or ``"posterior"`` (paper eq. 1-3).
        gravity: acceleration (3,), m/s^2 (stage units/s^2 for USD scenes).
        fused: run a frame's substeps in one launch per strand group, state kept on chip
            (:mod:`dftl_warp.kernels.solvers.fused`; identical results). ``None``: on CUDA, for the frames
            where the H200 measurements say it is faster (:func:`fused_pays`).
        scale_pushes: a follower's correction that pushes its leader is scaled by how far short of
            a segment the follower moved in the step (:func:`~dftl_warp.kernels.solvers.ftl.carried_func`):
            folded, fast strands do not thrash (docs/accuracy/folded.md). False: the paper's whole
            correction, as before 2026-11-28, whose fused substeps of 32-particle strands are about
            a fifth faster on an H200 (docs/benchmarks.md).
    """

    name = "dftl"
    options = ("damping", "correction", "fused", "scale_pushes")

    def __init__(self, model, *, damping: float = 1.0, correction: str = "prior", gravity=DEFAULT_GRAVITY,
                 fused: bool | None = None, scale_pushes: bool = True):
        if correction not in CORRECTIONS:
            raise ValueError(f"unknown correction {correction!r}; choose prior or posterior")
        # a string or a bool was taken through float() / bool(): fused="no" turned fused substeps on
        check_damping(damping)
        if fused is not None:
            check_bool("fused", fused)
        check_bool("scale_pushes", scale_pushes)
        super().__init__(model, gravity=gravity)
        self.damping = float(damping)
        self.correction = correction
        self.scale_pushes = bool(scale_pushes)
        # the step specialized to the model's features; a gravity-only model gets the bare kernel
        self._kernel = (step_kernel(model.scalar, correction, scale_pushes=self.scale_pushes)
                        if not model.feature_flags else None)
        self._features = None
        if model.feature_flags:
            from ..features.step import FeatureStep, velocity_pass_flags

            # hair-hair, drag and wind in their own pass; the sweep keeps the colliders (or is bare)
            pass_flags, sweep_flags = velocity_pass_flags(model.feature_flags)
            self._kernel = step_kernel(model.scalar, correction, sweep_flags, scale_pushes=self.scale_pushes)
            self._features = FeatureStep(model, self._kernel, velocity_form="velocity" if pass_flags else None)
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
        self._fused_runs = (fused_runs(model.layout.strand_count, model.scalar, correction, longest=on_chip,
                                       scale_pushes=self.scale_pushes) if self.fused else [])
        self._fused_block_dims = [fused_block_dim(model.scalar, fused_capacity(model.layout.strand_count[first]))
                                  for _, first, _ in self._fused_runs]
        self._pipelined_runs = pipelined_runs(model.layout, on_chip) if self.fused else []
        self._lane_scratch: dict = {}

    @staticmethod
    def carries(correction: str) -> bool:
        return correction == "prior"

    @property
    def carries_corrections(self) -> bool:
        return self.carries(self.correction)

    def step(self, state_in, state_out, control, dt: float, root_alpha: float = 1.0) -> None:
        """Advance ``state_in`` by ``dt`` seconds into ``state_out`` (which may be ``state_in``).

        Roots are placed ``root_alpha`` in [0, 1] of the way along ``control``'s root path.
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
            control.root_start, control.root_end, control.root_deviation_start, control.root_deviation_end, root_alpha,
            m.rest_lengths, self.gravity, dt, self.damping,
            state_in.positions, state_in.velocities,
        ]
        outputs = [state_out.positions, state_out.velocities]
        if self.carries_corrections:  # both states have corrections: checked above
            inputs.append(state_in.corrections)
            outputs.append(state_out.corrections)
        wp.launch(self._kernel, dim=m.num_strands, inputs=inputs, outputs=outputs, device=m.device)

    def feature_head(self, control, dt: float, root_alpha: float) -> list:
        """The leading inputs of the featured sweep (:meth:`FeatureStep.sweep
        <dftl_warp.features.step.FeatureStep.sweep>`)."""
        m = self.model
        return [m.strand_base, m.strand_stride, m.strand_count, control.root_start, control.root_end,
                control.root_deviation_start, control.root_deviation_end, root_alpha, m.rest_lengths, self.gravity,
                dt, self.damping]

    def step_on_grid(self, state, control, dt: float, root_alpha: float) -> None:
        """A featured substep's sweep in place once its collider poses and hair-hair grid are set (a
        groom split over devices builds the grid of all its parts first:
        :class:`~dftl_warp.simulation.multi_device.SplitSolver`)."""
        self._features.sweep(state, state, control, self.feature_head(control, dt, root_alpha))

    def advance(self, state, control, dt: float, substeps: int) -> None:
        """``substeps`` steps of ``dt`` in place, roots moving along the Control's root path: fused into one
        launch per run of strands where that pays (:func:`fused_pays`), else one launch per
        substep. On CUDA the frame is captured once in a CUDA graph and replayed afterwards. The
        results are not checked (no read-back: :meth:`Solver.advance <dftl_warp.solvers.base.Solver.advance>`).
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
            else:
                self.substeps(state, control, dt, substeps)

        curved = control.root_path_curved

        def kernels():
            pipelined = ([pipelined_kernel(m.scalar, substeps, curved, self.scale_pushes)]
                         if use_fused and self._pipelined_runs else [])
            return self.kernels() + pipelined

        self.launch_frame(state, control, dt, substeps, run, kernels, variant=(curved,))

    def kernels(self) -> list:
        kernels = self._features.kernels() if self._features is not None else [self._kernel]
        return kernels + [run[0] for run in self._fused_runs]

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
                        control.root_end, control.root_deviation_start, control.root_deviation_end, m.rest_lengths,
                        self.gravity, dt, self.damping, substeps,
                        state.positions, state.velocities, state.corrections],
                device=m.device,
            )
        for run in self._pipelined_runs:
            head = [run.first, run.strands, run.groups, run.count, run.base, run.strand_step, run.chunk, run.stride,
                    control.root_start, control.root_end, control.root_deviation_start, control.root_deviation_end,
                    m.rest_lengths, self.gravity, dt, self.damping]
            tail = [state.positions, state.velocities, state.corrections]
            if m.device.is_cuda:
                wp.launch(pipelined_kernel(m.scalar, substeps, control.root_path_curved, self.scale_pushes),
                          dim=run.groups * substeps,
                          block_dim=PIPELINED_BLOCK,
                          inputs=head + tail, device=m.device)
            else:
                vectors, scalars = self._lanes(run.groups * substeps)
                wp.launch(pipelined_serial_kernel(m.scalar, control.root_path_curved, self.scale_pushes), dim=run.groups,
                          inputs=head + [substeps, vectors, scalars] + tail, device=m.device)

    def _lanes(self, rows: int):
        """Scratch lane states of the serial pipelined kernel (at least ``rows`` lanes)."""
        m = self.model
        if self._lane_scratch.get("rows", 0) < rows:
            self._lane_scratch = {"rows": rows,
                                  "vectors": wp.empty((rows, 6), dtype=m.vec3, device=m.device),
                                  "scalars": wp.empty((rows, 2), dtype=m.scalar, device=m.device)}
        return self._lane_scratch["vectors"], self._lane_scratch["scalars"]


@register
class FTLSolver(DFTLSolver):
    """Follow-the-leader without velocity correction: :class:`DFTLSolver` with damping 0."""

    name = "ftl"
    options = ("correction", "fused")

    def __init__(self, model, *, correction: str = "prior", gravity=DEFAULT_GRAVITY, fused: bool | None = None):
        super().__init__(model, damping=0.0, correction=correction, gravity=gravity, fused=fused)
