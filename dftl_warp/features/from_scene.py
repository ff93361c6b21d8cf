"""A USD :class:`~dftl_warp.usd.scene.Scene`'s features: colliders from its ColliderPrims, the
``dftl:`` feature attributes, roots bound to a ``dftl:rootMesh``; and their per-frame animation.

Everything stays in stage units. Collider transforms are split into a rigid pose (per frame) and a
scale (from the first frame, baked into the geometry: box half extents, mesh points; spheres take
their largest scale, capsules the largest across their axis).
"""

from __future__ import annotations

import numpy as np

from ..errors import UserError
from .attributes import features_from_attributes
from .objects import Box, Capsule, Colliders, RootBinding, Sphere, TriangleMesh

_AXIS = {"X": 0, "Y": 1, "Z": 2}


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


def _shape(c, matrix, where):
    position, rotation, scale = split_matrix(matrix)
    a = np.abs(scale)
    friction = 0.3 if c.friction is None else c.friction
    common = dict(position=position, rotation=rotation, friction=friction, name=c.path)
    if c.kind == "sphere":
        return Sphere(radius=c.radius * a.max(), **common)
    if c.kind == "capsule":
        axis = _AXIS.get(str(c.axis).upper(), 2)
        across = np.delete(a, axis).max()
        return Capsule(radius=c.radius * across, half_height=0.5 * c.height * a[axis], axis="XYZ"[axis], **common)
    if c.kind == "box":
        return Box(half_extents=np.asarray(c.half_extents) * a, **common)
    if c.kind == "mesh":
        tris = np.asarray(c.triangles)
        if np.prod(np.sign(scale)) < 0:
            tris = tris[:, ::-1]  # a mirror turns the faces inside out; turn them back
        return TriangleMesh(points=np.asarray(c.mesh_points) * scale, indices=tris, **common)
    raise UserError(f"{where}: collider kind {c.kind!r} is not supported")


def widths_per_point(curve) -> np.ndarray | None:
    """Hair widths (stage units) per point of a curves prim, or None when not authored."""
    w = curve.widths
    if w is None or w.size == 0:
        return None
    if w.size == 1:
        return np.full(curve.num_points, float(w[0]))
    if w.size == curve.num_points:
        return w.astype(np.float64)
    if w.size == curve.num_strands:
        return np.repeat(w, curve.counts).astype(np.float64)
    return np.full(curve.num_points, float(np.mean(w)))  # e.g. varying widths of cubic curves


def group_features(scene, curves, frame) -> tuple[list, np.ndarray | None]:
    """(features, widths per point or None) of the curves prims ``curves`` simulated together."""
    feats = []
    where = scene.source
    if scene.colliders:
        shapes = [_shape(c, c.transform(frame), f"{where}: {c.path}") for c in scene.colliders]
        iterations = int(scene.features.get("dftl:collisionIterations", 2))
        if iterations < 1:
            raise UserError(f"{where}: dftl:collisionIterations = {iterations}: must be >= 1")
        feats.append(Colliders(shapes, iterations=iterations))
    seg = [np.linalg.norm(np.diff(c.points, axis=0), axis=1).mean() for c in curves if c.num_points > 1]
    try:
        feats += features_from_attributes(
            scene.features, [dict(c.features, path=f"{where}: {c.path}") for c in curves],
            [c.num_strands for c in curves], mean_segment=float(np.mean(seg)) if seg else 0.0, where=where)
    except ValueError as exc:
        raise UserError(str(exc)) from None
    mesh = curves[0].root_mesh
    if mesh is not None:
        feats.append(RootBinding(mesh.world_points(frame), mesh.triangles))
    widths = [widths_per_point(c) for c in curves]
    if all(w is None for w in widths):
        return feats, None
    return feats, np.concatenate([np.zeros(c.num_points) if w is None else w for c, w in zip(curves, widths)])


def update_frame(scene, curves, control, frame: int, nxt: int) -> None:
    """Set ``control``'s per-frame feature data for the frame ``frame`` -> ``nxt`` (time codes)."""
    fc = control.features
    if fc is None:
        return
    tcps = scene.stage.time_codes_per_second
    if fc.pose_start is not None and any(c.animated for c in scene.colliders):
        def poses(t):
            rows = []
            for c in scene.colliders:
                p, q, _ = split_matrix(c.transform(t))
                rows.append(np.concatenate([p, q]))
            return np.array(rows)

        fc.set_collider_poses(poses(frame), poses(nxt))
    for i, c in enumerate(scene.colliders):
        if c.kind == "mesh" and c.points_sampler is not None:
            _, _, scale = split_matrix(c.transform(frame))
            fc.set_mesh_points(i, c.points_sampler(nxt) * scale)
    if fc.wind is not None:
        fc.set_frame_time(frame / tcps, nxt / tcps)
    mesh = curves[0].root_mesh
    if mesh is not None and mesh.animated:
        fc.set_binding_points(mesh.world_points(frame), mesh.world_points(nxt))


def feature_names(flags) -> list[str]:
    """Readable names of kernel flags, for ``dftl-warp info``."""
    names = {"spheres": "sphere colliders", "capsules": "capsule colliders", "boxes": "box colliders",
             "meshes": "mesh colliders", "drag": "air drag", "wind": "wind", "wind_noise": "wind noise",
             "hair_hair": "hair-hair interaction", "shape": "shape retention"}
    return [names[f] for f in sorted(flags)]

