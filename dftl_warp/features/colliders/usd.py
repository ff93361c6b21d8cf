"""Colliders of a USD Scene: prims with ``UsdPhysics.CollisionAPI``
(:class:`~dftl_warp.usd.scene.ColliderPrim`), each made into the registered shape whose
``usd_kind`` it has. Transforms split into a rigid pose (animated per frame) and a scale (from the
first frame, baked into the geometry). Friction: the prim's (``dftl:friction``, else its physics
material's), else 0.3.
"""

from __future__ import annotations

import warnings

import numpy as np

from ...errors import UserError
from .base import SHAPES, ColliderApproximationWarning, Colliders, warn_approximation
from .sdf import FieldTooLarge

#: a transform whose normalized axes are further than this from orthogonal has shear
SHEAR = 1.0e-6


def _quat_from_rotation(r: np.ndarray) -> np.ndarray:
    """Unit quaternion (x, y, z, w) of a proper rotation matrix (column-vector convention)."""
    t = np.trace(r)
    if t > 0:
        s = 2.0 * np.sqrt(t + 1.0)
        q = [(r[2, 1] - r[1, 2]) / s, (r[0, 2] - r[2, 0]) / s, (r[1, 0] - r[0, 1]) / s, 0.25 * s]
    else:
        i = int(np.argmax(np.diag(r)))
        j, k = (i + 1) % 3, (i + 2) % 3
        s = 2.0 * np.sqrt(1.0 + r[i, i] - r[j, j] - r[k, k])
        q = [0.0, 0.0, 0.0, (r[k, j] - r[j, k]) / s]
        q[i] = 0.25 * s
        q[j] = (r[j, i] + r[i, j]) / s
        q[k] = (r[k, i] + r[i, k]) / s
    q = np.asarray(q)
    return q / np.linalg.norm(q)


def split_matrix(m: np.ndarray):
    """A 4x4 row-vector matrix -> (position (3,), rotation quaternion (4,), scale (3,)).

    ``scale[i]`` is the length of local axis ``i`` in the world (negative for the first axis of a
    mirroring transform); shear is dropped (the nearest rotation is kept).
    """
    lin = np.asarray(m, dtype=np.float64)[:3, :3]
    scale = np.linalg.norm(lin, axis=1)
    if np.any(scale < 1e-300):
        raise ValueError("zero scale")
    rows = lin / scale[:, None]
    if np.linalg.det(rows) < 0:
        scale[0], rows[0] = -scale[0], -rows[0]
    u, _, vt = np.linalg.svd(rows)
    rows = u @ vt  # nearest rotation (drops shear)
    return np.asarray(m, dtype=np.float64)[3, :3].copy(), _quat_from_rotation(rows.T), scale


def shape_from_prim(prim, matrix, where: str):
    """The collider shape of ``prim`` under the 4x4 row-vector ``matrix``."""
    position, rotation, scale = split_matrix(matrix)
    lin = np.asarray(matrix, dtype=np.float64)[:3, :3]
    axes = lin / np.linalg.norm(lin, axis=1)[:, None]
    shear = float(np.abs(axes @ axes.T - np.eye(3)).max())
    if shear > SHEAR:
        warn_approximation(prim.path, (
            f"its transform has shear (axes up to {np.degrees(np.arcsin(min(shear, 1.0))):.3g} degrees from "
            f"orthogonal), dropped: simulated under the nearest rotation and the axes' scales"))
    friction = 0.3 if prim.friction is None else prim.friction
    common = dict(position=position, rotation=rotation, friction=friction, name=prim.path)
    for cls in SHAPES.values():
        if cls.usd_kind == prim.kind:
            try:
                return cls.from_prim(prim, position, rotation, scale, common)
            except FieldTooLarge as exc:   # a signed distance field's cell too small for the mesh
                raise UserError(f"{where}: {exc}") from None
    raise UserError(f"{where}: collider kind {prim.kind!r} is not supported")


def from_scene(scene, frame) -> list:
    """The Colliders of ``scene`` at ``frame`` (none when it has no collider prims)."""
    if not scene.colliders:
        return []
    where = scene.source
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", ColliderApproximationWarning)
        shapes = [shape_from_prim(c, c.transform(frame), f"{where}: {c.path}") for c in scene.colliders]
    notes = getattr(scene, "warnings", None)
    for w in caught:
        if not issubclass(w.category, ColliderApproximationWarning):
            warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
            continue
        message = f"{where}: {w.message}"
        if notes is None:
            warnings.warn(message, ColliderApproximationWarning, stacklevel=2)
        elif message not in notes:  # once per prim and message (every group reads the colliders)
            notes.append(message)
    iterations = int(scene.features.get("dftl:collisionIterations", 2))
    if iterations < 1:
        raise UserError(f"{where}: dftl:collisionIterations = {iterations}: must be >= 1")
    return [Colliders(shapes, iterations=iterations)]


def update_from_scene(scene, fc, frame, nxt, shot=None) -> None:
    """Collider poses and deforming mesh points for the frame ``frame`` -> ``nxt`` (time codes): the
    meshes move from their points at ``frame`` to those at ``nxt`` through the frame.

    With ``shot`` (the first and last frame simulated) animated colliders follow the roots' C1 path
    inside the frame: the rates of their poses at ``frame`` and ``nxt`` are the fourth-order
    differences over the neighbouring frames that the roots' velocities are
    (:func:`~dftl_warp.core.state.frame_velocity`, one-sided at the shot's ends), the quaternions
    of those frames taken on the hemisphere of the one at ``frame``. Without it they move linearly
    (translation lerp, rotation slerp)."""
    if fc.pose_start is not None and any(c.animated for c in scene.colliders):
        cache = {}

        def poses(t):
            if t not in cache:
                rows = []
                for c in scene.colliders:
                    p, q, _ = split_matrix(c.transform(t))
                    rows.append(np.concatenate([p, q]))
                cache[t] = np.array(rows, dtype=np.float64)
            return cache[t]

        if shot is None:
            fc.set_collider_poses(poses(frame), poses(nxt))
        else:
            from ...core.state import frame_velocity
            from .device import hemisphere_signs

            here = poses(frame)

            def aligned(t):   # the same rotations, quaternions on the hemisphere of ``frame``'s
                rows = poses(t).copy()
                rows[:, 3:] *= hemisphere_signs(rows, here)
                return rows

            duration = (nxt - frame) / float(scene.stage.time_codes_per_second)
            fc.set_collider_poses(here, aligned(nxt),
                                  rate_start=frame_velocity(aligned, frame, *shot, duration),
                                  rate_end=frame_velocity(aligned, nxt, *shot, duration), frame_duration=duration)
    for i, c in enumerate(scene.colliders):
        if c.kind == "mesh" and c.points_sampler is not None:
            _, _, scale = split_matrix(c.transform(frame))
            # the mesh moves from the frame's points to the next's; where it is now is known unless
            # a saved state was restored
            start = c.points_sampler(frame) * scale if fc.colliders.mesh_stale(i) else None
            fc.set_mesh_points(i, c.points_sampler(nxt) * scale, start=start)
