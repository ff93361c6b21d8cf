"""Position Based Dynamics: the classic competitor, which trades stretch for speed.

``solver="pbd"`` with ``iterations=K`` Gauss-Seidel sweeps of distance constraints per step, the
root pinned to its target; see :mod:`dftl_warp.kernels.pbd`. Same interface as
:class:`~dftl_warp.solver.DFTLSolver`.
"""

from __future__ import annotations

import numpy as np
import warp as wp

from .kernels.pbd import pbd_kernel
from .solver import DEFAULT_GRAVITY, DFTLSolver


class PBDSolver:
    """Gauss-Seidel PBD for strands (equal unit masses, kinematic roots).

    Args:
        model: the :class:`~dftl_warp.model.Model` to simulate.
        iterations: Gauss-Seidel sweeps per step (K >= 1).
        gravity: acceleration (3,), m/s^2.
    """

    name = "pbd"
    carries_corrections = False

    def __init__(self, model, *, iterations: int = 4, gravity=DEFAULT_GRAVITY):
        if int(iterations) < 1:
            raise ValueError(f"iterations must be >= 1, got {iterations}")
        self.model = model
        self.iterations = int(iterations)
        self.gravity = model.vec3(*np.asarray(gravity, dtype=np.float64).reshape(3))
        self._kernel = pbd_kernel(model.scalar)
        self._graphs: dict = {}

    def state(self):
        """A rest State (positions and velocities only)."""
        return self.model.state(with_corrections=False)

    def step(self, state_in, state_out, control, dt: float, root_alpha: float = 1.0) -> None:
        """Advance ``state_in`` by ``dt`` seconds into ``state_out`` (which may be ``state_in``)."""
        m = self.model
        if m.num_strands == 0:
            return
        wp.launch(
            self._kernel,
            dim=m.num_strands,
            inputs=[m.strand_base, m.strand_stride, m.strand_count, control.root_start, control.root_end,
                    root_alpha, m.rest_lengths, self.gravity, dt, self.iterations,
                    state_in.positions, state_in.velocities],
            outputs=[state_out.positions, state_out.velocities],
            device=m.device,
        )

    def advance(self, state, control, dt: float, substeps: int) -> None:
        """``substeps`` steps of ``dt`` in place, roots moving linearly across them (a CUDA graph,
        captured once per state, control, dt and substeps, on the GPU, as for DFTL)."""
        m = self.model

        def run():
            for k in range(substeps):
                self.step(state, state, control, dt, (k + 1) / substeps)

        if m.num_strands == 0 or not m.device.is_cuda:
            run()
            return
        key = (id(state), id(control), float(dt), int(substeps))
        graph = self._graphs.get(key)
        if graph is None:
            self._kernel.module.load(m.device)
            with wp.ScopedCapture(device=m.device) as capture:
                run()
            graph = self._graphs[key] = capture.graph
        wp.capture_launch(graph)

    diagnostics = DFTLSolver.diagnostics
