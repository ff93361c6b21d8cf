"""Shared helpers of the feature modules: validation, per-strand values, numpy quaternions,
authored-attribute parsing.

Quaternions are ``(x, y, z, w)`` like Warp's (``wp.quat_rotate``).
"""

from __future__ import annotations

import numpy as np


def vector(value, n: int, what: str) -> np.ndarray:
    """``value`` as ``n`` finite float64 numbers, or ValueError naming ``what``."""
    a = np.asarray(value, dtype=np.float64).reshape(-1)
    if a.shape != (n,) or not np.isfinite(a).all():
        raise ValueError(f"{what} must be {n} finite numbers, got {value!r}")
    return a


def finite_rows(value, width: int, what: str) -> np.ndarray:
    """``value`` as (N, ``width``) finite float64 rows (a copy); ValueError naming ``what`` for
    another shape and naming the first row that is not finite."""
    try:
        a = np.array(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"{what} must be an (N, {width}) array of numbers, got {value!r}") from None
    if a.ndim > 2 or (a.ndim == 2 and a.shape[1] != width) or a.size % width:
        raise ValueError(f"{what} must be an (N, {width}) array, got shape {a.shape}")
    a = a.reshape(-1, width)
    if not np.isfinite(a).all():   # (all() of the whole array: 20x faster than row by row)
        i = int(np.flatnonzero(~np.isfinite(a).all(axis=1))[0])
        raise ValueError(f"{what}: row {i} is not finite ({a[i].tolist()})")
    return a


def quaternion_rows(rows: np.ndarray, what: str) -> None:
    """ValueError naming ``what`` and the row where the quaternion columns 3:7 of ``rows`` (N, 7)
    have (near) zero length: no rotation to normalise."""
    norm = np.linalg.norm(rows[:, 3:7], axis=1)
    bad = norm < 1e-12
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise ValueError(f"{what}: row {i} has a zero-length quaternion (qx, qy, qz, qw) = {rows[i, 3:7].tolist()}")


def unit_quaternion(rotation, what: str = "rotation") -> np.ndarray:
    """``rotation`` (x, y, z, w) normalized; ValueError for a zero or non-finite one.

    A non-unit quaternion is accepted and normalised (it names the same rotation), as the
    collider poses of :meth:`~dftl_warp.features.step.FeatureControl.set_collider_poses` are."""
    q = vector(rotation, 4, f"{what} (quaternion x, y, z, w)")
    norm = np.linalg.norm(q)
    if norm < 1e-12:
        raise ValueError(f"{what} quaternion is zero")
    return q / norm


def nonnegative(value, what: str) -> float:
    value = float(value)
    if not np.isfinite(value) or value < 0.0:
        raise ValueError(f"{what} must be a finite number >= 0, got {value}")
    return value


def positive(value, what: str, unit: str) -> float:
    """``value`` as a float; ValueError naming ``what`` unless it is a finite number > 0 (not a bool)."""
    if (isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, float, np.integer, np.floating))
            or not (np.isfinite(value) and value > 0)):
        raise ValueError(f"{what} must be a finite number > 0 ({unit}), got {value!r}")
    return float(value)


def per_strand(value, num_strands: int, what: str) -> np.ndarray:
    """One value, or one per strand (input order), as ``num_strands`` float64 values."""
    a = np.asarray(value, dtype=np.float64)
    if a.ndim == 0:
        return np.full(num_strands, float(a))
    if a.shape != (num_strands,):
        raise ValueError(f"{what}: expected one value or {num_strands} (one per strand), got shape {a.shape}")
    return a


def find(features, kind):
    """The feature of type ``kind`` in ``features``, or None."""
    for f in features or ():
        if isinstance(f, kind):
            return f
    return None


# -- numpy quaternions (x, y, z, w) -------------------------------------------------------------------


def quat_rotate(q, v):
    u, w = q[..., :3], q[..., 3:]
    t = 2.0 * np.cross(u, v)
    return v + w * t + np.cross(u, t)


# -- authored dftl: attributes --------------------------------------------------------------------------


def authored(values: dict, name: str, where: str, kind, default=None):
    """The authored value ``values[name]`` as ``kind`` (float, int or bool), or ``default`` when
    unset; ValueError naming ``where`` and the attribute for a bad one."""
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


def authored_per_strand(scene: dict, curves: list, counts: list, name: str, where: str, check) -> np.ndarray:
    """A ``dftl:`` value per strand: the curves prim's own, else the scene's (0 when neither);
    ``check(value, message)`` raises for a bad one."""
    base = authored(scene, name, where, float, 0.0)
    out = np.empty(sum(int(c) for c in counts))
    at = 0
    for values, n in zip(curves, counts):
        v = authored(values, name, values.get("path", "curves"), float, base)
        check(v, f"{values.get('path', 'curves')}: {name} = {v}")
        out[at:at + int(n)] = v
        at += int(n)
    check(base, f"{where}: {name} = {base}")
    return out
