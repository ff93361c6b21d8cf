"""Guide strands as curves with frames (numpy, float64): the reference the device kernels mirror.

A guide of ``n`` vertices has, at each vertex ``i``:

- a position ``P[i]``;
- a unit tangent ``T[i]``: the first segment's direction at the root, the last one's at the tip, the
  normalised sum of the two adjacent segment directions in between;
- a unit normal ``N[i]``, perpendicular to ``T[i]``: at the root, the direction to the guide's
  *reference point* (another guide's root, or a vertex of its own) made perpendicular to ``T[0]``;
  then carried vertex to vertex by parallel transport (the smallest rotation taking ``T[i-1]`` to
  ``T[i]``);
- the binormal ``B = T x N``.

Every step is built from positions alone, so a rigid motion of all guides (rotation + translation)
moves every frame rigidly. At arc-length fraction ``t`` between vertices ``i`` and ``i + 1``
(fraction ``u`` of the way), the position is ``(1 - u) P[i] + u P[i+1]``, the tangent the normalised
blend of ``T[i]`` and ``T[i+1]`` and the normal the blend of ``N[i]`` and ``N[i+1]`` made
perpendicular to it: continuous along the guide, exact at the vertices.
"""

from __future__ import annotations

import numpy as np

#: below this, 1 + cos(angle between tangents) counts as a U-turn: the normal is only projected
U_TURN = 1.0e-6


def normalize(v: np.ndarray) -> np.ndarray:
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    return np.divide(v, n, out=np.zeros_like(v), where=n > 0)


def fallback_axis(t: np.ndarray) -> np.ndarray:
    """The world axis least aligned with each tangent (a guide with no reference point)."""
    axis = np.zeros_like(t)
    axis[np.arange(t.shape[0]), np.argmin(np.abs(t), axis=-1)] = 1.0
    return axis


def transport(n: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Normals ``n`` (perpendicular to unit ``a``) carried by the smallest rotation taking ``a`` to ``b``."""
    v = np.cross(a, b)
    c = np.sum(a * b, axis=-1, keepdims=True)
    ok = 1.0 + c > U_TURN
    denom = np.where(ok, 1.0 + c, 1.0)
    r = np.where(ok, n * c + np.cross(v, n) + v * (np.sum(v * n, axis=-1, keepdims=True) / denom), n)
    return normalize(r - b * np.sum(r * b, axis=-1, keepdims=True))


def guide_frames(points, starts, counts, ref_guide, ref_vertex):
    """(P, T, N) at every guide vertex, compact (same order as ``points``).

    ``ref_guide[g]``, ``ref_vertex[g]``: the guide and vertex whose position sets guide ``g``'s root
    normal (``ref_guide < 0``: the world axis least aligned with the root tangent)."""
    P = np.asarray(points, dtype=np.float64)
    starts, counts = np.asarray(starts), np.asarray(counts)
    T = np.zeros_like(P)
    N = np.zeros_like(P)
    G = counts.shape[0]
    seg = np.zeros_like(P)  # seg[s + i]: unit direction of segment i of a strand (i < n - 1)
    inner = np.ones(P.shape[0], dtype=bool)
    inner[starts + counts - 1] = False
    idx = np.flatnonzero(inner)
    seg[idx] = normalize(P[idx + 1] - P[idx])
    # vertex tangents
    T[idx] = seg[idx]
    tips = starts + counts - 1
    T[tips] = seg[tips - 1]
    mid = idx[np.isin(idx, starts, invert=True)]
    both = normalize(seg[mid - 1] + seg[mid])
    zero = np.linalg.norm(both, axis=-1) == 0
    both[zero] = seg[mid][zero]
    T[mid] = both
    # root normals
    t0 = T[starts]
    ref_guide, ref_vertex = np.asarray(ref_guide), np.asarray(ref_vertex)
    has = ref_guide >= 0
    d = fallback_axis(t0)
    d[has] = P[starts[ref_guide[has]] + ref_vertex[has]] - P[starts[has]]
    n0 = normalize(d - t0 * np.sum(d * t0, axis=-1, keepdims=True))
    bad = np.linalg.norm(n0, axis=-1) == 0
    if bad.any():  # reference on the tangent line: the world axis instead
        d2 = fallback_axis(t0[bad])
        n0[bad] = normalize(d2 - t0[bad] * np.sum(d2 * t0[bad], axis=-1, keepdims=True))
    N[starts] = n0
    for i in range(1, int(counts.max()) if G else 0):
        live = np.flatnonzero(counts > i)
        v = starts[live] + i
        N[v] = transport(N[v - 1], T[v - 1], T[v])
    return P, T, N


def arc_fractions(points, starts, counts, normalise: bool = True) -> np.ndarray:
    """Arc-length fraction (0 at the root, 1 at the tip) of every vertex, float64; ``normalise=False``:
    the arc length itself."""
    P = np.asarray(points, dtype=np.float64)
    d = np.zeros(P.shape[0])
    d[1:] = np.linalg.norm(P[1:] - P[:-1], axis=-1)
    d[starts] = 0.0
    strand = np.repeat(np.arange(len(counts)), counts)
    cum = np.cumsum(d)
    cum -= cum[starts][strand]
    if not normalise:
        return cum
    total = cum[starts + counts - 1][strand]
    return np.divide(cum, total, out=np.zeros_like(cum), where=total > 0)


def locate(frac, starts, counts, g, t):
    """Segment (global index of its first vertex) and fraction ``u`` of arc parameter ``t`` (fraction or
    length, as ``frac``) on guides ``g``; past the tip, the last segment at ``u = 1``."""
    g = np.asarray(g)
    t = np.asarray(t, dtype=np.float64)
    width = 2.0 * (max(float(frac.max(initial=0.0)), float(t.max(initial=0.0))) + 1.0)
    key = np.repeat(np.arange(len(counts)), counts) * width + frac  # sorted, one band per guide
    i = np.searchsorted(key, g * width + np.maximum(t, 0.0), side="right") - 1
    i = np.clip(i, starts[g], starts[g] + counts[g] - 2)
    a0, a1 = frac[i], frac[i + 1]
    span = a1 - a0
    u = np.clip(np.divide(t - a0, span, out=np.zeros_like(t), where=span > 0), 0.0, 1.0)
    return i, u


def sample(P, T, N, i, u):
    """Position, tangent, normal and binormal at segment ``i``, fraction ``u``."""
    u = u[..., None]
    p = (1.0 - u) * P[i] + u * P[i + 1]
    t = normalize((1.0 - u) * T[i] + u * T[i + 1])
    n = (1.0 - u) * N[i] + u * N[i + 1]
    n = normalize(n - t * np.sum(n * t, axis=-1, keepdims=True))
    return p, t, n, np.cross(t, n)
