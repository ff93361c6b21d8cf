"""The colliders' motion, for the energy monitor (:mod:`dftl_warp.simulation.monitor`): how fast each
collider's surface moved over the frame just simulated, and where it went.

A moving collider does work on the hair as a moving root does: a surface moving at ``U`` throws a
particle at up to about ``2 U`` (an elastic bounce off it), and friction drags hair along. Each
check, :meth:`ColliderMotion.update` reads the frame's poses from the Control (the path the
colliders followed inside the frame: linear, or the roots' C1 path when the poses came with rates,
:class:`~dftl_warp.features.colliders.ColliderControl`) and gives, per device collider:

- ``speed``: a bound on its surface's speed over the frame (m/s, model units): at ``SAMPLES``
  points of the frame's path, the largest ``(|dp| + R dtheta) / dt`` of its origin's step ``dp``
  and its rotation's angle ``dtheta`` (``R``: the radius around its origin that holds the whole
  shape: the sum of an analytic shape's sizes, the farthest point of a mesh), plus, for a mesh whose
  points changed since the last check (a deforming, time-sampled mesh), its largest point
  displacement over the frame's duration;
- ``center``, ``reach``: a sphere (device coordinates) that holds the collider wherever it was
  during the frame.

The energy kernel (``kernels/simulation/energy.py``) then gives each strand the fastest of the
moving colliders that can reach it: those whose sphere lies within the strand's reach of its root.
A collider that does not move has speed 0 and changes nothing.

The mesh colliders' points at the last check are kept on the device (one copy per mesh), and saved
with the monitor's records (:meth:`save`), so that a resumed run measures the next frame's
deformation as the uninterrupted one does.
"""

from __future__ import annotations

import math

import numpy as np
import warp as wp

from ..kernels.simulation.energy import mesh_motion_kernel

#: points of the frame's path at which the poses are sampled (the path's steps between them)
SAMPLES = 8


def _unit(q: np.ndarray) -> np.ndarray:
    return q / np.linalg.norm(q, axis=-1, keepdims=True)


class ColliderMotion:
    """The colliders of ``control`` (a Control whose model has colliders) as the energy monitor
    sees them; ``frame_duration`` (s): the time of one frame, over which the Control's poses move.
    See the module docstring."""

    def __init__(self, control, frame_duration: float):
        duration = float(frame_duration)
        if not (math.isfinite(duration) and duration > 0):
            raise ValueError(f"the energy monitor's frame_duration must be a finite number of seconds > 0, "
                             f"got {frame_duration!r}")
        self.duration = duration
        self.colliders = cc = control.features.colliders
        data = cc.data
        device = control.model.device
        shapes = [None] * len(data.colliders.shapes)
        for user, shape in enumerate(data.colliders.shapes):
            shapes[int(data.order[user])] = shape
        self.count = len(shapes)
        #: per device collider: the radius around its origin that holds it (meshes: from their points)
        self._radius = np.array([0.0 if s.kind == "meshes" else float(np.abs(s.size_axis()[0]).sum())
                                 for s in shapes])
        self._mesh_data = meshes = cc.kind_data.get("meshes")
        #: device collider -> (its user index, its mesh's points at the last check); a moving mesh's
        #: live points are in whichever of its two meshes the step queries now (``mesh_now``)
        self._meshes = {c: (user, wp.clone(mesh.points)) for user, (c, mesh) in
                        (meshes.meshes.items() if meshes is not None else ())}
        self._mesh_out = wp.zeros(max(2 * len(self._meshes), 1), dtype=wp.float64, device=device)
        for c, (_, points) in self._meshes.items():
            self._radius[c] = float(np.linalg.norm(points.numpy(), axis=1).max(initial=0.0))
        self.center = wp.zeros(self.count, dtype=wp.vec3d, device=device)
        self.reach = wp.zeros(self.count, dtype=wp.float64, device=device)
        self.speed = wp.zeros(self.count, dtype=wp.float64, device=device)

    def update(self, first: bool) -> None:
        """The frame's motion into :attr:`center`, :attr:`reach` and :attr:`speed` (zero speeds
        when ``first``: the check measures the start of the run, not a frame)."""
        radius, deformation = self._radius.copy(), np.zeros(self.count)
        if self._meshes:
            self._mesh_out.zero_()
            for k, (user, before) in enumerate(self._meshes.values()):
                points = self._mesh_data.mesh_now(user).points
                wp.launch(mesh_motion_kernel(), dim=points.shape[0], device=points.device,
                          inputs=[points, 2 * k], outputs=[before, self._mesh_out])
            out = self._mesh_out.numpy()
            for k, c in enumerate(self._meshes):
                deformation[c] = out[2 * k]
                radius[c] = max(radius[c], out[2 * k + 1])   # the larger of the last check's and now
                self._radius[c] = out[2 * k + 1]
        p, q = self._path()
        step_time = self.duration / SAMPLES
        dp = np.linalg.norm(np.diff(p, axis=1), axis=2)
        dq = np.diff(q, axis=1)
        dtheta = 4.0 * np.arcsin(np.minimum(np.linalg.norm(dq, axis=2) / 2.0, 1.0))
        speed = (dp + radius[:, None] * dtheta).max(axis=1) / step_time + deformation / self.duration
        lower, upper = p.min(axis=1), p.max(axis=1)
        center = 0.5 * (lower + upper)
        reach = radius + np.linalg.norm(p - center[:, None], axis=2).max(axis=1)
        self.center.assign(center)
        self.reach.assign(reach)
        self.speed.assign(np.zeros(self.count) if first else speed)

    def _path(self) -> tuple[np.ndarray, np.ndarray]:
        """Origins (C, SAMPLES + 1, 3) and unit quaternions (C, SAMPLES + 1, 4, on one hemisphere)
        along the frame's path (the pose kernel's, ``kernels/features/collide.py``, with a
        normalised linear blend of the quaternions in place of the slerp on the linear path: the
        same rotations, at most a little faster midway)."""
        cc = self.colliders
        start, end = (np.asarray(a.numpy(), dtype=np.float64).reshape(-1, 7) for a in (cc.pose_start, cc.pose_end))
        if cc.curved:
            d0, d1 = (np.asarray(a.numpy(), dtype=np.float64).reshape(-1, 7)
                      for a in (cc.deviation_start, cc.deviation_end))
        else:
            d0 = d1 = np.zeros_like(start)
        a = (np.arange(SAMPLES + 1) / SAMPLES)[None, :, None]
        b = 1.0 - a
        rows = (start[:, None] + a * (end - start)[:, None]
                + (a * b) * (b * d0[:, None] - a * d1[:, None]))
        q = _unit(rows[..., 3:])
        q *= np.where(np.sum(q * q[:, :1], axis=2, keepdims=True) < 0.0, -1.0, 1.0)
        return rows[..., :3], q

    def save(self) -> dict:
        """The mesh colliders' points at the last check (numpy; :meth:`load`)."""
        return {f"mesh{c}": before.numpy() for c, (_, before) in self._meshes.items()}

    def load(self, saved: dict) -> None:
        for c, (_, before) in self._meshes.items():
            values = np.asarray(saved[f"mesh{c}"])
            if values.shape != tuple(before.shape) + (3,):
                raise ValueError(f"saved mesh collider {c} has {values.shape[0]} points, not {before.shape[0]}")
            before.assign(wp.array(values, dtype=before.dtype, device=before.device))
            self._radius[c] = float(np.linalg.norm(values, axis=1).max(initial=0.0))
