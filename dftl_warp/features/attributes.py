"""The ``dftl:`` attributes that turn features on in a scene, and their mapping to feature objects.

Scene-wide values are authored on the stage's physics scene prim (``UsdPhysics.Scene``) or, when
there is none, on the default prim; per-curve values on a ``BasisCurves`` prim override the scene's
for that prim's curves. Lengths are in stage units, times in seconds. Colliders come from prims
with ``UsdPhysics.CollisionAPI`` (friction: ``dftl:friction``, read with the prim).

:func:`features_from_attributes` takes the authored values as plain dicts (no USD objects), so
it is the same whoever reads the stage.
"""

from __future__ import annotations

import numpy as np

from .objects import Drag, HairHair, ShapeRetention, Wind

#: name -> (type, where: "scene", "curves" or "both", description)
ATTRIBUTES = {
    "dftl:drag": (float, "both", "air drag rate (1/s): velocities relax toward the air's velocity; 0 or unset: no drag"),
    "dftl:wind": ("float3", "scene", "wind velocity (stage units/s), time-sampled for gusts; needs dftl:drag > 0"),
    "dftl:windNoise": (float, "scene", "curl-noise amplitude added to the wind (stage units/s)"),
    "dftl:windNoiseScale": (float, "scene", "feature size of the noise (stage units)"),
    "dftl:windNoiseFrequency": (float, "scene", "how fast the noise changes (1/s)"),
    "dftl:windSeed": (int, "scene", "noise field selector"),
    "dftl:hairHair": (bool, "scene", "true turns hair-hair interaction on"),
    "dftl:hairHairCellSize": (float, "scene", "grid cell size (stage units); default 4 x the mean segment length"),
    "dftl:hairHairFriction": (float, "scene", "rate (1/s) of relaxation toward the local mean velocity"),
    "dftl:hairHairRepulsion": (float, "scene", "acceleration (stage units/s^2) per unit density difference across a cell"),
    "dftl:shapeStiffness": (float, "both", "shape retention in [0, 1] per substep; 0 or unset: off"),
    "dftl:collisionIterations": (int, "scene", "collide-and-restore rounds per particle (>= 1, default 2)"),
    "dftl:rootMesh": ("rel", "curves", "a Mesh prim the roots are bound to (closest point at rest); follows its animated points"),
}


def _get(values, name, where, kind, default=None):
    if name not in values or values[name] is None:
        return default
    v = values[name]
    try:
        if kind is float:
            v = float(v)
            if not np.isfinite(v):
                raise ValueError
        elif kind is int:
            v = int(v)
        elif kind is bool:
            v = bool(v)
    except (TypeError, ValueError):
        raise ValueError(f"{where}: {name} = {values[name]!r}: expected {kind.__name__}") from None
    return v


def features_from_attributes(scene: dict, curves: list, counts: list, *, mean_segment: float = 0.0,
                             where: str = "scene") -> list:
    """Feature objects for authored ``dftl:`` values.

    Args:
        scene: scene-wide values (name -> value; ``dftl:wind`` may be (3,) or keyframes (K, 4)
            of (seconds, vx, vy, vz)).
        curves: one dict per curves prim (with an optional ``"path"`` for messages).
        counts: strands in each curves prim, same order.
        mean_segment: mean rest segment length (stage units), for the default grid cell.

    Returns the features the attributes turn on (possibly none); raises ``ValueError`` naming the
    prim and attribute for a bad value.
    """
    feats = []
    counts = [int(c) for c in counts]
    total = sum(counts)

    def per_strand(name, check):
        base = _get(scene, name, where, float, 0.0)
        out = np.empty(total)
        at = 0
        for values, n in zip(curves, counts):
            v = _get(values, name, values.get("path", "curves"), float, base)
            check(v, f"{values.get('path', 'curves')}: {name} = {v}")
            out[at:at + n] = v
            at += n
        check(base, f"{where}: {name} = {base}")
        return out

    def nonneg(v, msg):
        if v < 0:
            raise ValueError(f"{msg}: must be >= 0")

    def unit(v, msg):
        if not 0 <= v <= 1:
            raise ValueError(f"{msg}: must be in [0, 1]")

    drag = per_strand("dftl:drag", nonneg)
    wind = scene.get("dftl:wind")
    if np.any(drag > 0) or wind is not None:
        if wind is not None and not np.any(drag > 0):
            raise ValueError(f"{where}: dftl:wind acts through air drag: author dftl:drag > 0")
        feats.append(Drag(drag))
        if wind is not None:
            try:
                feats.append(Wind(
                    velocity=np.asarray(wind, dtype=np.float64),
                    noise_amplitude=_get(scene, "dftl:windNoise", where, float, 0.0),
                    noise_scale=_get(scene, "dftl:windNoiseScale", where, float, 0.1),
                    noise_frequency=_get(scene, "dftl:windNoiseFrequency", where, float, 1.0),
                    seed=_get(scene, "dftl:windSeed", where, int, 0)))
            except ValueError as exc:
                raise ValueError(f"{where}: dftl:wind: {exc}") from None
    if _get(scene, "dftl:hairHair", where, bool, False):
        cell = _get(scene, "dftl:hairHairCellSize", where, float, 4.0 * mean_segment)
        if not cell > 0:
            raise ValueError(f"{where}: dftl:hairHairCellSize = {cell}: must be > 0")
        feats.append(HairHair(cell_size=cell, friction=_get(scene, "dftl:hairHairFriction", where, float, 2.0),
                              repulsion=_get(scene, "dftl:hairHairRepulsion", where, float, 5.0)))
    stiffness = per_strand("dftl:shapeStiffness", unit)
    if np.any(stiffness > 0):
        feats.append(ShapeRetention(stiffness))
    return feats
