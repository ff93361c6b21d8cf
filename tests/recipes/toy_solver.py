# dftl_warp/solvers/toy.py
"""A toy solver (the solver recipe of docs/architecture.md): explicit Euler, then one
follow-the-leader pass restoring each segment's rest length."""

from __future__ import annotations

import warp as wp

from ..kernels.solvers.toy import toy_kernel
from .base import DEFAULT_GRAVITY, Solver, register


@register
class ToySolver(Solver):
    name = "toy"

    def __init__(self, model, *, gravity=DEFAULT_GRAVITY):
        super().__init__(model, gravity=gravity)
        self._kernel = toy_kernel(model.scalar)

    def step(self, state_in, state_out, control, dt: float, root_alpha: float = 1.0) -> None:
        m = self.model
        if m.num_strands == 0:
            return
        wp.launch(self._kernel, dim=m.num_strands,
                  inputs=[m.strand_base, m.strand_stride, m.strand_count, control.root_start, control.root_end,
                          root_alpha, m.rest_lengths, self.gravity, dt, state_in.positions, state_in.velocities],
                  outputs=[state_out.positions, state_out.velocities], device=m.device)

    def kernels(self) -> list:
        return [self._kernel]
