"""Per-frame output of a simulation: device state -> local-space samples on the host.

One :class:`LocalSamples` serves one model (one device): it gathers the particles back into the
input order and transforms them into each prim's local space on the device
(:mod:`dftl_warp.kernels.output.samples`), in float32 (what USD stores), then copies them into pinned
host buffers allocated once. :meth:`launch` only enqueues that work, so several devices can
work at once; :meth:`fetch` waits and returns arrays the caller owns.
"""

from __future__ import annotations

import numpy as np
import warp as wp

from ..kernels.output.samples import local_samples_kernel


class LocalSamples:
    """Output buffers of one model; ``member_of_point`` (N,) is each input point's prim index."""

    def __init__(self, model, member_of_point: np.ndarray):
        d = self.device = model.device
        n = int(member_of_point.shape[0])
        self.slots = wp.array(model.layout.slot_of_point.astype(np.int32), dtype=wp.int32, device=d)
        self.member = wp.array(member_of_point.astype(np.int32), dtype=wp.int32, device=d)
        self.points = wp.empty(n, dtype=wp.vec3f, device=d)
        self.velocities = wp.empty(n, dtype=wp.vec3f, device=d)
        pinned = d.is_cuda
        self.host_points = wp.empty(n, dtype=wp.vec3f, device="cpu", pinned=pinned) if pinned else self.points
        self.host_velocities = wp.empty(n, dtype=wp.vec3f, device="cpu", pinned=pinned) if pinned else self.velocities

    def launch(self, model, state, to_local: np.ndarray, rate: np.ndarray) -> None:
        """Enqueue the transform (column-vector world-to-local matrices and frame rates per
        prim) and the copy to the host."""
        d = self.device
        wp.launch(
            local_samples_kernel(model.scalar), dim=self.points.shape[0], device=d,
            inputs=[self.slots, self.member, wp.vec3d(*model.origin),
                    wp.array(to_local, dtype=wp.mat44d, device=d), wp.array(rate, dtype=wp.mat44d, device=d),
                    state.positions, state.velocities],
            outputs=[self.points, self.velocities],
        )
        if self.host_points is not self.points:
            wp.copy(self.host_points, self.points)
            wp.copy(self.host_velocities, self.velocities)

    def fetch(self, owned: bool = True) -> tuple[np.ndarray, np.ndarray]:
        """Wait for :meth:`launch`; (N, 3) float32 points and velocities the caller owns, or
        (``owned=False``) views of the host buffers, valid until the next :meth:`launch`."""
        wp.synchronize_device(self.device)
        points = self.host_points.numpy().reshape(-1, 3)
        velocities = self.host_velocities.numpy().reshape(-1, 3)
        return (points.copy(), velocities.copy()) if owned else (points, velocities)
