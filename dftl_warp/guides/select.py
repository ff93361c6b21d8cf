"""Choosing guides from a dense groom (numpy).

- ``"fps"``: farthest-point sampling of the roots weighted by strand length: start from the longest
  strand, then repeatedly take the strand with the largest ``length x distance from its root to the
  nearest chosen root``. Long strands, which move most, are covered more densely.
- ``"kmeans"``: k-means (Lloyd, k-means++ seeding, weighted by strand length) of the roots together
  with the root directions (scaled to the expected cluster radius), then in each cluster the strand
  nearest its centre.

Both are ``O(S x n)`` in time (brute-force distances, in chunks): fine up to a few hundred thousand
strands x tens of thousands of guides.
"""

from __future__ import annotations

import numpy as np

from ..errors import plural
from .binding import check_strands, nearest
from .frames import normalize

METHODS = ("fps", "kmeans")


def fraction_strands(fraction: float, num_strands: int) -> int:
    """The strands a ``fraction`` of ``num_strands`` rounds to (0 for a fraction too small)."""
    return int(round(float(fraction) * num_strands))


def guide_count(n_or_fraction, num_strands: int) -> int:
    """Number of guides: an integer ``n`` (1..S) or a fraction in (0, 1] of the strands."""
    v = n_or_fraction
    if isinstance(v, (bool, np.bool_)):
        raise ValueError(f"n_or_fraction must be a count or a fraction, got {v!r}")
    if isinstance(v, (int, np.integer)):
        n = int(v)
    elif isinstance(v, (float, np.floating)) and 0.0 < float(v) <= 1.0:
        n = max(1, fraction_strands(v, num_strands))
    else:
        raise ValueError(f"n_or_fraction must be an integer >= 1 or a fraction in (0, 1], got {v!r}")
    if not 1 <= n <= num_strands:
        raise ValueError(f"n_or_fraction asks for {plural(n, 'guide')} from {plural(num_strands, 'strand')}")
    return n


def strand_lengths(points, counts, starts) -> np.ndarray:
    seg = np.linalg.norm(np.diff(points, axis=0), axis=1)
    seg = np.concatenate([seg, [0.0]])
    ends = starts + counts - 1
    seg[ends] = 0.0
    return np.add.reduceat(seg, starts) if counts.size else np.zeros(0)


def select_guides(points, counts, n_or_fraction, method: str = "fps", *, seed: int = 0, iterations: int = 25,
                  direction_weight: float | None = None) -> np.ndarray:
    """Indices (sorted, distinct) of the strands to simulate as guides.

    Args:
        points: (N, 3) concatenated strand vertices, root first; counts: (S,) vertices per strand (>= 2).
        n_or_fraction: number of guides, or a fraction in (0, 1] of the strands.
        method: ``"fps"`` or ``"kmeans"`` (module docstring).
        seed: k-means++ seeding; iterations: Lloyd iterations of k-means.
        direction_weight: length that a root-direction difference of 1 counts as in k-means (default:
            the expected cluster radius, the mean root spacing x sqrt(S / n)).

    Raises:
        ValueError naming the argument.
    """
    p, c, s = check_strands(points, counts)
    S = c.shape[0]
    if S == 0:
        raise ValueError("counts is empty: no strands to choose guides from")
    n = guide_count(n_or_fraction, S)
    if method not in METHODS:
        raise ValueError(f"method must be one of {', '.join(METHODS)}, got {method!r}")
    roots = p[s]
    lengths = strand_lengths(p, c, s)
    if method == "fps":
        return _fps(roots, lengths, n)
    return _kmeans(p, c, s, roots, lengths, n, seed, iterations, direction_weight)


def _fps(roots, lengths, n):
    S = roots.shape[0]
    w = lengths / max(lengths.mean(), 1e-300) + 1e-12
    chosen = np.zeros(n, dtype=np.int64)
    chosen[0] = int(np.argmax(lengths))
    dist = np.linalg.norm(roots - roots[chosen[0]], axis=1)
    taken = np.zeros(S, dtype=bool)
    taken[chosen[0]] = True
    for m in range(1, n):
        score = np.where(taken, -1.0, dist * w)
        i = int(np.argmax(score))
        chosen[m] = i
        taken[i] = True
        dist = np.minimum(dist, np.linalg.norm(roots - roots[i], axis=1))
    return np.sort(chosen)


def _kmeans(p, c, s, roots, lengths, n, seed, iterations, direction_weight):
    S = roots.shape[0]
    look = s + np.minimum(3, c - 1)  # a few segments in: the direction the strand leaves the scalp
    direction = normalize(p[look] - roots)
    if direction_weight is None:
        if S > 1:
            _, d = nearest(roots, roots, 1, exclude_self=True)
            spacing = float(np.mean(d[:, 0]))
        else:
            spacing = 0.0
        direction_weight = spacing * np.sqrt(S / n)
    x = np.concatenate([roots, float(direction_weight) * direction], axis=1)
    w = lengths + 1e-12 * max(lengths.max(), 1e-300)
    rng = np.random.default_rng(seed)
    # k-means++ seeding
    centers = np.empty((n, 6))
    centers[0] = x[rng.choice(S, p=w / w.sum())]
    d2 = np.sum((x - centers[0]) ** 2, axis=1)
    for m in range(1, n):
        prob = d2 * w
        total = prob.sum()
        i = rng.choice(S, p=prob / total) if total > 0 else int(rng.integers(S))
        centers[m] = x[i]
        d2 = np.minimum(d2, np.sum((x - centers[m]) ** 2, axis=1))
    label = np.zeros(S, dtype=np.int64)
    for _ in range(iterations):
        idx, _ = nearest(x, centers, 1)
        new = idx[:, 0]
        sums = np.zeros((n, 6))
        np.add.at(sums, new, x * w[:, None])
        mass = np.bincount(new, weights=w, minlength=n)
        empty = mass <= 0
        centers[~empty] = sums[~empty] / mass[~empty, None]
        if empty.any():  # re-seed empty clusters at the worst-fit strands
            far = np.argsort(-np.sum((x - centers[new]) ** 2, axis=1))[: int(empty.sum())]
            centers[empty] = x[far]
        if np.array_equal(new, label) and not empty.any():
            break
        label = new
    # one strand per cluster: the member nearest the centre (distinct; a cluster left empty takes the
    # strand nearest its centre among those not yet chosen)
    d = np.sum((x - centers[label]) ** 2, axis=1)
    chosen = np.full(n, -1, dtype=np.int64)
    order = np.lexsort((d, label))
    first = np.ones(S, dtype=bool)
    first[1:] = label[order][1:] != label[order][:-1]
    heads = order[first]
    chosen[label[heads]] = heads
    taken = np.zeros(S, dtype=bool)
    taken[heads] = True
    for m in np.flatnonzero(chosen < 0):
        dm = np.where(taken, np.inf, np.sum((x - centers[m]) ** 2, axis=1))
        i = int(np.argmin(dm))
        chosen[m] = i
        taken[i] = True
    return np.sort(chosen)
