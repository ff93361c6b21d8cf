"""A USD :class:`~dftl_warp.usd.scene.Scene`'s features, composed from each feature's USD mapping:
colliders from its ColliderPrims, the ``dftl:`` feature attributes, roots bound to a
``dftl:rootMesh``; and their per-frame animation. Everything stays in stage units.

:func:`features_from_attributes` takes the authored values as plain dicts (no USD objects), so
it is the same whoever reads the stage. Scene-wide values are authored on the stage's physics
scene prim (``UsdPhysics.Scene``) or, when there is none, on the default prim; per-curve values on
a ``BasisCurves`` prim override the scene's for that prim's curves. Lengths are in stage units,
times in seconds.
"""

from __future__ import annotations

import numpy as np

from ..errors import UserError
from ..usd.curves import varying_per_vertex
from . import air, binding, colliders, hair_hair

#: every ``dftl:`` feature attribute: name -> (type, where: "scene", "curves" or "both", description)
ATTRIBUTES = {**air.ATTRIBUTES, **hair_hair.ATTRIBUTES, **colliders.ATTRIBUTES,
              **binding.ATTRIBUTES}


def features_from_attributes(scene: dict, curves: list, counts: list, *, mean_segment: float = 0.0,
                             where: str = "scene", meters_per_unit: float = 1.0) -> list:
    """Feature objects for authored ``dftl:`` values.

    Args:
        scene: scene-wide values (name -> value; ``dftl:wind`` may be (3,) or keyframes (K, 4)
            of (seconds, vx, vy, vz)).
        curves: one dict per curves prim (with an optional ``"path"`` for messages).
        counts: strands in each curves prim, same order.
        mean_segment: mean rest segment length (stage units), for the default grid cell.
        meters_per_unit: the stage's unit, for defaults given in SI units.

    Returns the features the attributes turn on (possibly none); raises ``ValueError`` naming the
    prim and attribute for a bad value.
    """
    counts = [int(c) for c in counts]
    return (air.from_attributes(scene, curves, counts, where)
            + hair_hair.from_attributes(scene, where, mean_segment, meters_per_unit))


def width_scale(matrix) -> float:
    """How a 4x4 row-vector transform scales hair widths: its mean scale |det L|^(1/3) (exact for
    a uniform scale; the renderer's rule, :mod:`dftl_warp.render.usd_scene`)."""
    return float(abs(np.linalg.det(np.asarray(matrix, dtype=np.float64)[:3, :3])) ** (1.0 / 3.0))


def widths_per_point(curve, frame=None) -> np.ndarray | None:
    """Hair widths (stage units, in the world: the authored local widths times the mean scale of
    the prim's transform at ``frame``, as its points are transformed) per point of a curves prim,
    or None when not authored."""
    w = curve.widths
    if w is None or w.size == 0:
        return None
    w = np.asarray(w, dtype=np.float64) * width_scale(curve.transform(frame))
    if curve.widths_interpolation in ("varying", "faceVarying") and curve.type == "cubic":
        return varying_per_vertex(w, curve.counts, curve.basis, curve.wrap)
    if w.size == 1:
        return np.full(curve.num_points, float(w[0]))
    if w.size == curve.num_points:
        return w
    if w.size == curve.num_strands:
        return np.repeat(w, curve.counts)
    raise ValueError(f"{curve.path}: {w.size} widths for {curve.num_points} points")


def segment_lengths(curve, frame) -> np.ndarray:
    """Lengths (stage units) of a curves prim's segments in the world at ``frame``, within its
    strands (not from one strand's tip to the next one's root)."""
    m = curve.transform(frame)
    d = np.linalg.norm(np.diff(curve.points @ m[:3, :3], axis=0), axis=1)
    return np.delete(d, np.cumsum(curve.counts)[:-1] - 1)


def group_features(scene, curves, frame) -> tuple[list, np.ndarray | None]:
    """(features, widths per point or None) of the curves prims ``curves`` simulated together."""
    where = scene.source
    feats = colliders.from_scene(scene, frame)
    seg = np.concatenate([segment_lengths(c, frame) for c in curves])
    try:
        feats += features_from_attributes(
            scene.features, [dict(c.features, path=f"{where}: {c.path}") for c in curves],
            [c.num_strands for c in curves], mean_segment=float(np.mean(seg)) if seg.size else 0.0, where=where,
            meters_per_unit=float(scene.stage.meters_per_unit))
    except ValueError as exc:
        raise UserError(str(exc)) from None
    feats += binding.from_scene(curves, frame)
    widths = [widths_per_point(c, frame) for c in curves]
    if all(w is None for w in widths):
        return feats, None
    return feats, np.concatenate([np.zeros(c.num_points) if w is None else w for c, w in zip(curves, widths)])


def update_frame(scene, curves, control, frame: int, nxt: int, shot=None) -> None:
    """Set ``control``'s per-frame feature data for the frame ``frame`` -> ``nxt`` (time codes):
    collider poses and mesh points, the wind's time, and the roots of a bound mesh (poses and bound
    roots on the C1 root path when ``shot``, the first and last frame simulated, is given)."""
    fc = control.features
    if fc is None:
        return
    colliders.update_from_scene(scene, fc, frame, nxt, shot=shot)
    if fc.wind is not None:
        tcps = scene.stage.time_codes_per_second
        fc.set_frame_time(frame / tcps, nxt / tcps)
    binding.update_from_scene(curves, control, frame, nxt, shot=shot,
                              time_codes_per_second=scene.stage.time_codes_per_second)


def feature_names(flags) -> list[str]:
    """Readable names of kernel flags, for ``dftl-warp info``."""
    names = {"drag": "air drag", "wind": "wind", "wind_noise": "wind noise",
             "hair_hair": "hair-hair interaction"}
    names.update({kind: f"{cls.usd_kind} colliders" for kind, cls in colliders.SHAPES.items()})
    return [names[f] for f in sorted(flags)]
