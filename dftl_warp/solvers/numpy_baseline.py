"""The numpy baseline: the same DFTL step vectorized over strands, as a user would write it.

Used to cross-check the Warp kernels (tests) and as the speed baseline (``scripts/bench.py``).
Strands are padded to the longest one: arrays are (S, n_max, 3); ``counts`` masks the padding.
"""

from __future__ import annotations

import numpy as np

from ..core.layout import strand_offsets
from ..kernels.solvers import ftl

def pad_strands(points, counts):
    """(N, 3) concatenated points -> (S, n_max, 3) padded array (padding repeats the last vertex)."""
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    counts = np.asarray(counts, dtype=np.int64)
    n_max = int(counts.max()) if counts.size else 0
    starts = strand_offsets(counts)
    local = np.minimum(np.arange(n_max)[None, :], counts[:, None] - 1)
    return points[starts[:, None] + local]


def unpad_strands(padded, counts):
    """Inverse of :func:`pad_strands`."""
    counts = np.asarray(counts, dtype=np.int64)
    mask = np.arange(padded.shape[1])[None, :] < counts[:, None]
    return padded[mask]


def _of_follower(values, counts):
    """``values`` of particle i+1 at index i; zero at each strand's tip and in the padding."""
    out = np.zeros_like(values)
    out[:, :-1] = values[:, 1:]
    out[np.arange(values.shape[1])[None, :] + 1 >= counts[:, None]] = 0.0
    return out


def step(x, v, corr, rest, counts, roots, *, dt, gravity, damping=1.0, correction="prior", degenerate=1e-12,
         scale_pushes=True):
    """One DFTL step on padded arrays; returns new ``(x, v, corr)``.

    x, v, corr: (S, n, 3); rest: (S, n) rest length of the segment ending at each particle;
    roots: (S, 3) root targets after the step. ``scale_pushes``: a follower's correction that
    pushes its leader is scaled by ``max(1 - a m, 0)``, ``m`` its motion in the step over its rest
    length and ``a`` ``ftl.PUSH_MOTION_SCALE``, as the kernels do (``kernels/solvers/ftl.py``; a push: the prediction within a rest
    length of the new leader); False: the paper's ``x - p``.
    """
    S, n, _ = x.shape
    g = np.asarray(gravity, dtype=x.dtype) * dt * dt
    xn = np.empty_like(x)
    vn = np.empty_like(v)
    cn = np.zeros_like(x)
    xn[:, 0] = roots
    vn[:, 0] = (roots - x[:, 0]) / dt
    p = x + dt * v + g
    if correction == "prior":
        p -= damping * _of_follower(corr, counts)
    pushes = np.zeros(x.shape[:2], dtype=bool)
    for i in range(1, n):
        d = p[:, i] - xn[:, i - 1]
        d2 = np.einsum("ij,ij->i", d, d)
        pushes[:, i] = d2 < rest[:, i] ** 2
        tol = rest[:, i] * degenerate
        ok = (d2 > tol * tol) & (d2 > 1e-30)
        fallback = x[:, i] - x[:, i - 1]
        f2 = np.einsum("ij,ij->i", fallback, fallback)
        unit_x = np.zeros_like(d)
        unit_x[:, 0] = 1.0
        direction = np.where(
            ok[:, None], d / np.sqrt(np.where(ok, d2, 1.0))[:, None],
            np.where((f2 > 1e-30)[:, None], fallback / np.sqrt(np.where(f2 > 1e-30, f2, 1.0))[:, None], unit_x),
        )
        xn[:, i] = xn[:, i - 1] + rest[:, i, None] * direction
    cn[:, 1:] = xn[:, 1:] - p[:, 1:]
    if scale_pushes:
        pushes = pushes[:, 1:]
        moved = np.linalg.norm(xn[:, 1:] - x[:, 1:], axis=2)
        share = np.maximum(rest[:, 1:] - ftl.PUSH_MOTION_SCALE * moved, 0.0) / np.where(pushes, rest[:, 1:], 1.0)
        cn[:, 1:] *= np.where(pushes, share, 1.0)[..., None]
    vn[:, 1:] = (xn[:, 1:] - x[:, 1:]) / dt
    if correction == "posterior":
        vn[:, 1:] -= damping * _of_follower(cn, counts)[:, 1:] / dt
        cn[:] = 0.0
    # padding follows its strand's last particle
    pad = np.arange(n)[None, :] >= counts[:, None]
    last = xn[np.arange(S), counts - 1]
    xn[pad] = np.broadcast_to(last[:, None, :], xn.shape)[pad]
    return xn, vn, cn


def simulate(points, counts, *, steps, dt, gravity, damping=1.0, correction="prior"):
    """Run ``steps`` steps with roots held; returns the final (N, 3) positions and velocities."""
    counts = np.asarray(counts, dtype=np.int64)
    x = pad_strands(points, counts)
    rest = np.zeros(x.shape[:2])
    rest[:, 1:] = np.linalg.norm(np.diff(x, axis=1), axis=2)
    v = np.zeros_like(x)
    c = np.zeros_like(x)
    roots = x[:, 0].copy()
    for _ in range(steps):
        x, v, c = step(x, v, c, rest, counts, roots, dt=dt, gravity=gravity, damping=damping, correction=correction)
    return unpad_strands(x, counts), unpad_strands(v, counts)
