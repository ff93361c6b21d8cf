"""The production second-order solver: RATTLE with a fixed number of Newton iterations.

Same dynamics as the float64 :class:`~dftl_warp.solvers.reference.ReferenceSolver` (the
inextensible chain, kinematic roots, unit masses), built for speed instead of certainty: the
model's precision (float32 by default), a fixed number of Newton iterations per step (no
data-dependent loop, no step halving), and a follow-the-leader projection after them that keeps
every length exact to round-off whether Newton converged or not. See
:mod:`dftl_warp.kernels.solvers.rattle` for the scheme.

Second order and energy-conserving where the Newton iterations converge (RATTLE is symplectic and
time-reversible: no numerical damping, unlike DFTL). Where they do not (a segment turning by tens of
degrees in one substep, a teleporting root), the projection acts like one FTL step on that strand:
first order and dissipative there, never NaN, never stretched. ``diagnostics()`` reports the
largest residual the projection removed from a converged solve (``constraint_residual``) and how
many strand-steps dropped a diverged Newton result (``fallbacks``) since the solver was built or
:meth:`RattleSolver.reset_statistics` was called.

On chip: strands of at most 32 vertices can run :mod:`dftl_warp.kernels.solvers.rattle_fused`,
the same arithmetic with the whole strand in thread-local storage (bitwise equal on the CPU);
``on_chip=True`` asks for it; the default is the global-memory kernel, which the H200 measured
faster (the on-chip kernel spills registers). Longer strands take the global-memory kernel.

Memory: besides the State, two vec3 and three scalars of scratch per particle (36 bytes in float32;
none when every strand runs on chip) and 8 bytes per strand; the scratch is the solver's, so one
solver advances one state at a time.
Features (colliders, drag, wind, hair-hair) are not part of this solver: it steps gravity and
roots only, and refuses a model with features.
"""

from __future__ import annotations

import numpy as np
import warp as wp

from ..core.layout import strand_offsets
from ..kernels.solvers.rattle import rattle_kernel
from ..kernels.solvers.rattle_fused import rattle_capacity, rattle_fused_kernel
from .base import DEFAULT_GRAVITY, Solver, check_bool, check_integer, check_no_features, check_real, register

#: Newton iterations per step: 3 bring the relative squared-length residual of a float32 groom at
#: production substeps (>= 8 per 1/24 s frame) to round-off (docs/accuracy-second-order.md)
DEFAULT_NEWTON_ITERATIONS = 3

#: relative squared-length residual below which the fixed Newton iterations count as converged
#: (the projection then removes the rest); above it the step is split in halves
DEFAULT_ACCEPT = 1.0e-4

#: halvings of a substep at most (a substep is split into at most 2^k pieces where the SHAKE
#: position equations have no solution along the old segments: a whipping tip, a teleporting root)
DEFAULT_MAX_HALVINGS = 3

#: relative squared-length residual above which a Newton result is treated as diverged and the
#: plain prediction is projected instead
DEFAULT_FALLBACK = 0.25


def rattle_runs(strand_count, scalar, on_chip: bool) -> list:
    """(kernel, first device strand, number of strands) for each run of consecutive device strands
    that share a kernel: the on-chip kernel of their capacity (8/16/24/32 vertices) when ``on_chip``,
    None for the global-memory kernel (longer strands, or ``on_chip`` off)."""
    counts = [int(c) for c in strand_count]
    if not counts:
        return []
    keys = [rattle_capacity(c) if on_chip else None for c in counts]
    runs, first = [], 0
    for s in range(1, len(keys) + 1):
        if s == len(keys) or keys[s] != keys[first]:
            kernel = rattle_fused_kernel(scalar, keys[first]) if keys[first] is not None else None
            runs.append((kernel, first, s - first))
            first = s
    return runs


@register
class RattleSolver(Solver):
    """RATTLE in the model's precision, ``newton_iterations`` Newton + Thomas solves per step.

    Args:
        model: the :class:`~dftl_warp.core.model.Model`; free particles need non-zero rest lengths.
        gravity: acceleration (3,), m/s^2 (stage units/s^2 for USD scenes).
        newton_iterations: Newton iterations of the position solve per step (fixed; >= 1).
        fallback: relative squared-length residual above which a Newton result (at the smallest
            piece) is dropped for the projection of the unconstrained prediction.
        accept: relative squared-length residual below which the fixed iterations count as
            converged; above it (and above ``max_halvings`` splits) the step is redone in halves.
        max_halvings: how many times a substep may be halved (at most ``2^max_halvings`` pieces).
        on_chip: run strands of at most 32 vertices with the on-chip kernel (default off: slower
            on the H200, see docs/accuracy-second-order.md).
    """

    name = "rattle"
    options = ("newton_iterations", "fallback", "accept", "max_halvings", "on_chip")

    def __init__(self, model, *, gravity=DEFAULT_GRAVITY, newton_iterations: int = DEFAULT_NEWTON_ITERATIONS,
                 fallback: float = DEFAULT_FALLBACK, accept: float = DEFAULT_ACCEPT,
                 max_halvings: int = DEFAULT_MAX_HALVINGS, on_chip: bool = False):
        newton_iterations = check_integer("newton_iterations", newton_iterations)
        fallback = check_real("fallback", fallback)
        accept = check_real("accept", accept)
        max_halvings = check_integer("max_halvings", max_halvings, minimum=0)
        if max_halvings > 10:
            raise ValueError(f"max_halvings must be an integer in [0, 10], got {max_halvings!r}")
        on_chip = check_bool("on_chip", on_chip)
        check_no_features(model, "rattle")
        rest = model.rest_lengths.numpy()[model.layout.slot_of_point]
        starts = strand_offsets(model.counts)
        free = np.ones(rest.shape[0], dtype=bool)
        free[starts[model.counts > 0]] = False
        if np.any(rest[free] <= 0.0):
            i = int(np.flatnonzero(free & (rest <= 0.0))[0])
            s = int(np.searchsorted(starts, i, side="right")) - 1
            k = i - int(starts[s])
            raise ValueError(f"strand {s} of the model, segment {k - 1}: points {k - 1} and {k} coincide (a "
                             "zero-length segment); the rattle solver needs non-zero rest lengths: remove the "
                             "coincident points, or use --solver dftl, which simulates them")
        super().__init__(model, gravity=gravity)
        self.newton_iterations = int(newton_iterations)
        self.fallback = float(fallback)
        self.accept = float(accept)
        self.max_halvings = int(max_halvings)
        self._kernel = rattle_kernel(model.scalar)
        # measured slower on the H200 (it spills: 255 registers and a 6 KB stack at 32 vertices),
        # so the global-memory kernel runs unless the on-chip one is asked for
        self.on_chip = bool(on_chip)
        self._runs = rattle_runs(model.layout.strand_count, model.scalar, self.on_chip)
        n, dev = model.num_slots, model.device
        if any(kernel is None for kernel, _, _ in self._runs):
            self._q = wp.zeros(n, dtype=model.vec3, device=dev)
            self._lo = wp.zeros(n, dtype=model.vec3, device=dev)
            self._scalars = [wp.zeros(n, dtype=model.scalar, device=dev) for _ in range(3)]
        self._residual = wp.zeros(model.num_strands, dtype=model.scalar, device=dev)
        self._fallbacks = wp.zeros(model.num_strands, dtype=wp.int32, device=dev)

    def kernels(self) -> list:
        return [self._kernel] + sorted({k for k, _, _ in self._runs if k is not None}, key=id)

    def _launch(self, state_in, state_out, control, dt, alpha_first, alpha_step, substeps):
        m = self.model
        if m.num_strands == 0:
            return
        if state_out is not state_in:
            wp.copy(state_out.positions, state_in.positions)
            wp.copy(state_out.velocities, state_in.velocities)
        common = [m.strand_base, m.strand_stride, m.strand_count, control.root_start, control.root_end,
                  control.root_deviation_start, control.root_deviation_end, alpha_first, alpha_step, int(substeps),
                  m.rest_lengths, self.gravity, dt,
                  self.newton_iterations, self.fallback, self.accept, self.max_halvings,
                  state_out.positions, state_out.velocities]
        for kernel, first, size in self._runs:
            if kernel is None:
                wp.launch(self._kernel, dim=size, device=m.device,
                          inputs=[first, *common, self._q, self._lo, *self._scalars, self._residual,
                                  self._fallbacks])
            else:
                wp.launch(kernel, dim=size, device=m.device,
                          inputs=[first, *common, self._residual, self._fallbacks])

    def step(self, state_in, state_out, control, dt: float, root_alpha: float = 1.0) -> None:
        """Advance ``state_in`` by ``dt`` seconds into ``state_out`` (which may be ``state_in``)."""
        self._launch(state_in, state_out, control, dt, root_alpha, 0.0, 1)

    def substeps(self, state, control, dt: float, substeps: int) -> None:
        """The frame's substeps in one launch (the substep loop runs inside the kernel)."""
        real = np.dtype(self.model.precision).type
        step = float(real(1.0) / real(substeps))
        self._launch(state, state, control, dt, step, step, substeps)

    def reset_statistics(self) -> None:
        """Zero the residual and fallback counters that :meth:`diagnostics` reports."""
        self._residual.zero_()
        self._fallbacks.zero_()

    def diagnostics(self, state) -> dict:
        """Energy (J/kg), max stretch, max speed (m/s), the largest relative squared-length residual
        the projection removed from a converged Newton solve (``constraint_residual``) and the
        number of strand-steps whose Newton result diverged and was dropped (``fallbacks``)."""
        out = super().diagnostics(state)
        if self.model.num_strands:
            out["constraint_residual"] = float(self._residual.numpy().max())
            out["fallbacks"] = int(self._fallbacks.numpy().sum())
        else:
            out["constraint_residual"], out["fallbacks"] = 0.0, 0
        return out
