"""Position Based Dynamics: the classic competitor, which trades stretch for speed.

``solver="pbd"`` with ``iterations=K`` Gauss-Seidel sweeps of distance constraints per step, the
root pinned to its target; see :mod:`dftl_warp.kernels.solvers.pbd`. Same interface as
:class:`~dftl_warp.solvers.dftl.DFTLSolver`.
"""

from __future__ import annotations

import numpy as np
import warp as wp

from ..kernels.solvers.pbd import pbd_kernel
from .base import DEFAULT_GRAVITY, Solver, check_integer, check_no_features, register


@register
class PBDSolver(Solver):
    """Gauss-Seidel PBD for strands (equal unit masses, kinematic roots); gravity and roots only: a
    model with features (colliders, drag, wind, hair-hair) is refused.

    Args:
        model: the :class:`~dftl_warp.core.model.Model` to simulate.
        iterations: Gauss-Seidel sweeps per step (K >= 1).
        gravity: acceleration (3,), m/s^2.
    """

    name = "pbd"
    options = ("iterations",)

    def __init__(self, model, *, iterations: int = 4, gravity=DEFAULT_GRAVITY):
        iterations = check_integer("iterations", iterations)
        check_no_features(model, "pbd")
        super().__init__(model, gravity=gravity)
        self.iterations = int(iterations)
        self._kernel = pbd_kernel(model.scalar)

    def step(self, state_in, state_out, control, dt: float, root_alpha: float = 1.0) -> None:
        """Advance ``state_in`` by ``dt`` seconds into ``state_out`` (which may be ``state_in``)."""
        m = self.model
        if m.num_strands == 0:
            return
        wp.launch(
            self._kernel,
            dim=m.num_strands,
            inputs=[m.strand_base, m.strand_stride, m.strand_count, control.root_start, control.root_end,
                    control.root_deviation_start, control.root_deviation_end, root_alpha, m.rest_lengths,
                    self.gravity, dt, self.iterations,
                    state_in.positions, state_in.velocities],
            outputs=[state_out.positions, state_out.velocities],
            device=m.device,
        )

    def kernels(self) -> list:
        return [self._kernel]

    def substeps(self, state, control, dt: float, substeps: int) -> None:
        for k in range(substeps):
            self.step(state, state, control, dt, (k + 1) / substeps)
