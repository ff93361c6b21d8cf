"""Is a strand's rest shape a stable equilibrium? (host side, numpy, float64)

Inverse statics (:mod:`.elastic_rest`) makes every authored shape an equilibrium under gravity, but
not every equilibrium is stable: hair standing up beyond its buckling length (a clamped column of
hair under its own weight buckles at ``L = 1.986 l_b``, Greenhill 1881, ``l_b = (EI / (rho A
g))^(1/3)``) is a broomstick balanced on end, and the smallest disturbance (round-off) makes it
fall. A game groom's gelled mohawk is such a shape for hair of human stiffness.

The test: the smallest eigenvalue of the stiffness at the rest shape, on the motions the solver
allows (the root and its clamp fixed, every segment's length kept), with the frames at the minimum
of the energy for each shape (the solver sets them so every step; they carry no inertia). In the
positions ``x`` and a small rotation ``w_j`` of each frame (``F_j = exp([w_j])``, identity at rest):

- the bending matrix ``K = D^T W D`` (the solver's bands ``k0, k1, k2``) plus the geometric
  stiffness of the inverse-statics tensions, ``T_k / l_k (I - e_k e_k^T)`` on each segment
  (negative under compression);
- the frames' coupling to the positions, ``W_j D_j^T [b_j]x``, and their own stiffness: from the
  bending, ``W_j (|b_j|^2 I - b_j b_j^T) - (r_j b_j^T + b_j r_j^T) / 2 + (r_j . b_j) I`` with ``r_j =
  (D x)_j - b_j`` the rest bending moment over ``W_j``; from each twist coupling ``G_j (3 - tr(F_j^T
  F_{j-1} Q_j))``, ``G_j (tr Q_j I - sym Q_j)`` on each of the two frames and ``G_j (Q_j - tr Q_j I)``
  between them (:class:`~dftl_warp.solvers.elastic_rest.RodGroup`'s energy; ``tests/test_elastic_stability.py``
  checks these blocks against its finite differences);
- the frames eliminated (the Schur complement), a negative eigenvalue is a direction in which the
  strand falls.

On a straight strand the frames decouple (``b = 0``, ``Q = I``) and this is the discrete Greenhill
problem (1.986 l_b within 1% at 32 segments). On curved ones the frames matter: on AMD's Ratboy
mohawk every strand that fell within 10 s at a static head was flagged, 15 of the 37 only through
the frames (docs/elastic.md, "Styles that cannot stand").
"""

from __future__ import annotations

import numpy as np

from .elastic_rest import skew, threaded_map


def _constrained(grp, rows):
    """The bending and geometric stiffness of the strands ``rows`` of ``grp`` at the rest shape,
    on the motions the constraints allow: (S, 2N, 2N) each; the basis of those motions (S, 3N, 2N);
    and the bending bands' scale."""
    S, N = rows.size, grp.N
    k0, k1, k2 = grp.k0[rows], grp.k1[rows], grp.k2[rows]
    T, lengths = grp.T_rest[rows], grp.l[rows]
    e = grp.rest_directions[rows, 1:]                             # (S, N, 3) unit, segment k = 1..N
    eye = np.eye(3)
    Kb = np.zeros((S, N, N, 3, 3))                                # free particles 1..N as rows 0..N-1
    Kg = np.zeros((S, N, N, 3, 3))
    kt = (T[:, 1:] / lengths[:, 1:N + 1])[..., None, None] * (eye - e[..., :, None] * e[..., None, :])
    for r in range(N):
        Kb[:, r, r] = k0[:, r + 1, None, None] * eye
        Kg[:, r, r] = kt[:, r]
        if r + 1 < N:
            Kb[:, r, r + 1] = Kb[:, r + 1, r] = k1[:, r + 1, None, None] * eye
            Kg[:, r, r + 1] = Kg[:, r + 1, r] = -kt[:, r + 1]
            Kg[:, r, r] += kt[:, r + 1]                           # segment r + 2 on its near end
        if r + 2 < N:
            Kb[:, r, r + 2] = Kb[:, r + 2, r] = k2[:, r + 1, None, None] * eye
    # the constraints e_k . (v_k - v_{k-1}) = 0 (v_0 = 0): their null space, from the SVD of J
    J = np.zeros((S, N, N, 3))
    for k in range(N):
        J[:, k, k] = e[:, k]
        if k:
            J[:, k, k - 1] = -e[:, k]
    _, _, vt = np.linalg.svd(J.reshape(S, N, 3 * N))
    basis = vt[:, N:].transpose(0, 2, 1)                         # (S, 3N, 2N)

    def project(K):
        H = basis.transpose(0, 2, 1) @ K.transpose(0, 1, 3, 2, 4).reshape(S, 3 * N, 3 * N) @ basis
        return 0.5 * (H + H.transpose(0, 2, 1))

    Hb, Hg = project(Kb), project(Kg)
    return Hb, Hg, basis, _scale(np.abs(k0[:, 1:]).max(axis=1), Hg)


def _scale(bending, Hg):
    """The margins' unit: the largest diagonal entry of the bending matrix, or of the geometric
    stiffness on strands with no bending at all (every ``bendStiffnessScale`` 0), or 1 (no load)."""
    geometric = np.abs(np.diagonal(Hg, axis1=1, axis2=2)).max(axis=1)
    return np.where(bending > 0, bending, np.where(geometric > 0, geometric, 1.0))


def frame_blocks(grp, rows):
    """The Hessian blocks of the frames at the rest shape (see the module): positions-frames (S,
    3N, 3N; rows the free particles 1..N, columns the frames 0..N-1) and frames-frames (S, 3N, 3N)."""
    S, N = rows.size, grp.N
    W, b, G, Q = grp.W[rows], grp.b[rows], grp.G[rows], grp.Qb[rows]
    al, ga = grp.alpha[rows], grp.gamma[rows]
    r = grp.apply_D(grp.rest, grp.ghost)[rows] - b               # the rest bending moments over W
    # D on the free particles: (D x)_j = alpha_j x_{j-1} - (alpha_j + gamma_j) x_j + gamma_j x_{j+1}
    D = np.zeros((S, N, N))
    for j in range(N):
        D[:, j, j] = ga[:, j]
        if j >= 1:
            D[:, j, j - 1] = -(al[:, j] + ga[:, j])
        if j >= 2:
            D[:, j, j - 2] = al[:, j]
    eye = np.eye(3)
    n = 3 * N
    cross = np.einsum('sj,sjp,sjab->spajb', W, D, skew(b)).reshape(S, n, n)
    outer = np.einsum('sja,sjb->sjab', r, b)
    own = W[..., None, None] * (np.sum(b * b, -1)[..., None, None] * eye - np.einsum('sja,sjb->sjab', b, b)
                                - 0.5 * (outer + outer.transpose(0, 1, 3, 2))
                                + np.sum(r * b, -1)[..., None, None] * eye)
    trace = np.trace(Q, axis1=-2, axis2=-1)[..., None, None]
    twist = G[..., None, None] * (trace * eye - 0.5 * (Q + Q.transpose(0, 1, 3, 2)))
    between = G[..., None, None] * (Q - trace * eye)             # coupling j: (w_j, w_{j-1})
    frames = np.zeros((S, n, n))
    for j in range(N):
        here = slice(3 * j, 3 * j + 3)
        frames[:, here, here] += own[:, j] + twist[:, j]
        if j >= 1:
            before = slice(3 * j - 3, 3 * j)
            frames[:, before, before] += twist[:, j]
            frames[:, here, before] += between[:, j]
            frames[:, before, here] += between[:, j].transpose(0, 2, 1)
    return cross, frames


def stiffness_margins(grp, rows=None) -> np.ndarray:
    """Per strand of a :class:`~dftl_warp.solvers.elastic_rest.RodGroup` (its ``rows``, or all): the
    smallest eigenvalue of the constrained stiffness at the rest shape, the frames eliminated, over
    the largest diagonal entry of the bending matrix (unitless). Below zero (beyond round-off): the
    rest shape is an unstable equilibrium (also where the frames alone are: ``-inf``)."""
    rows = np.arange(grp.S) if rows is None else np.asarray(rows)
    if grp.N < 2:
        return np.ones(rows.size)
    Hb, Hg, basis, scale = _constrained(grp, rows)
    cross, frames = frame_blocks(grp, rows)
    held = np.linalg.eigvalsh(frames)[:, 0] > 0.0
    coupled = basis.transpose(0, 2, 1) @ cross                    # (S, 2N, 3N)
    H = Hb + Hg
    H[held] -= coupled[held] @ np.linalg.solve(frames[held], coupled[held].transpose(0, 2, 1))
    H = 0.5 * (H + H.transpose(0, 2, 1))
    return np.where(held, np.linalg.eigvalsh(H)[:, 0] / scale, -np.inf)


def holding_scales(grp, rows=None, *, tolerance: float = 0.002, smallest: float = 1.0e-3,
                   largest: float = 1.0e6) -> np.ndarray:
    """Per strand: the smallest factor on its bending stiffness (``bendStiffnessScale``) that makes
    its rest shape a stable equilibrium, within ``tolerance`` (relative); 0 where the strand holds at
    ``smallest`` (tension holds it); ``largest`` where nothing up to it does, ``inf`` if the strand
    has a vertex of scale 0 (a hinge, which no factor stiffens). Each trial rebuilds
    the strands (:meth:`~dftl_warp.solvers.elastic_rest.RodGroup.scaled`: inverse statics and the
    twist couplings change with the stiffness); the search starts from the bending-only answer, the
    largest ``s`` with ``det(s Hb + Hg) = 0`` on the constrained motions, which is exact on straight
    strands (their frames decouple)."""
    rows = np.arange(grp.S) if rows is None else np.asarray(rows)
    if grp.N < 2 or rows.size == 0:
        return np.zeros(rows.size)
    Hb, Hg, _, _ = _constrained(grp, rows)
    hinged = (grp.W[rows] <= 0.0).any(axis=1)                 # a vertex of scale 0, which no factor stiffens
    bending = np.zeros(rows.size)                              # for those the search starts from ``smallest``
    bending[~hinged] = _bending_estimate(Hb[~hinged], Hg[~hinged])

    def holds(idx, factors):
        # the margin in units of the unscaled bending (a margin over the scaled one tends to 0 as
        # the factor grows even where the factor does not help: at a hinge)
        return stiffness_margins(grp.scaled(rows[idx], factors)) * np.maximum(factors, 1.0) >= -1.0e-12

    step = 1.0 + tolerance
    hi = np.maximum(bending * (1.0 + 1e-6), smallest)          # a factor that holds, once found
    lo = np.maximum(bending / step, smallest) / step           # one that does not (0: none)
    todo = np.arange(rows.size)
    while todo.size:                                           # raise hi until it holds
        good = holds(todo, hi[todo])
        grow = todo[~good & (hi[todo] < largest)]
        lo[grow] = hi[grow]
        hi[grow] = np.minimum(hi[grow] * 4.0, largest)
        todo = grow
    todo = np.flatnonzero(lo < hi)
    while todo.size:                                           # lower lo until it does not
        good = holds(todo, lo[todo])
        hi[todo[good]] = lo[todo[good]]
        lo[todo[good]] = lo[todo[good]] / 4.0
        lo[todo[good & (lo[todo] < smallest)]] = 0.0
        todo = todo[good & (lo[todo] > 0.0)]
    todo = np.flatnonzero((lo > 0.0) & (hi > lo * step))
    while todo.size:                                           # bisect (geometric)
        mid = np.sqrt(lo[todo] * hi[todo])
        good = holds(todo, mid)
        hi[todo[good]] = mid[good]
        lo[todo[~good]] = mid[~good]
        todo = todo[hi[todo] > lo[todo] * step]
    out = np.where(lo > 0.0, hi, 0.0)
    return np.where(hinged & (out >= largest), np.inf, out)


def _bending_estimate(Hb, Hg) -> np.ndarray:
    """Per strand, the largest ``s`` >= 0 with ``det(s Hb + Hg) = 0``, ``Hb`` positive definite (no
    vertex of zero stiffness): the factor from which the bending alone holds it."""
    if Hb.shape[0] == 0:
        return np.zeros(0)
    Li = np.linalg.inv(np.linalg.cholesky(Hb))
    return np.maximum(np.linalg.eigvalsh(Li @ (-Hg) @ Li.transpose(0, 2, 1))[:, -1], 0.0)


def _within(cost, budget) -> np.ndarray:
    """Which of the tests of ``cost`` (in the random order) fit the ``budget`` when taken in turn,
    each one that fits in what is left (a strand costlier than the budget alone is skipped, not the
    end of the sample: a prefix of the order stopped at the first long strand, which left every
    strand after it untested)."""
    keep = np.zeros(cost.size, dtype=bool)
    left = float(budget)
    for i, c in enumerate(cost):
        if c <= left:
            keep[i] = True
            left -= c
    return keep


def longest_tested(budget: int = 2500) -> int:
    """The most segments a strand tested within ``budget`` can have (434 at the default)."""
    n = int(32.0 * budget ** (1.0 / 3.0)) + 1
    while n ** 3 > budget * 32.0 ** 3:
        n -= 1
    return n


def too_long(groups, budget: int = 2500) -> np.ndarray:
    """Input indices of the strands that :func:`unstable_strands` never tests within ``budget``:
    each alone costs more ((segments / 32)^3 units: more than :func:`longest_tested` segments)."""
    long = [idx for _, idx, grp in groups if grp.N > longest_tested(budget)]
    return np.sort(np.concatenate(long + [np.zeros(0, np.int64)]))


def unstable_strands(groups, *, budget: int = 2500, scale_sample: int = 64, seed: int = 0):
    """Strands whose rest shape is an unstable equilibrium, from the solver's rest groups ((count,
    input strand indices, RodGroup) triples): every strand of two or more segments (through its
    frames a strand can fall without a compressed segment) when that costs no more than ``budget``
    strands of 32 segments (the test's cost grows as the cube of the segments: about 1.5 ms for 32
    on the 2-core VM), else a random sample within that budget (strands costlier than the budget
    alone are never tested: :func:`too_long`). Returns (unstable input
    strand indices among those tested, the :func:`holding_scales` of up to ``scale_sample`` of them
    drawn at random (each a search over rebuilt strands: about 20 ms a strand), strands tested,
    strands that could be). Strands whose authored shape needs a moment at a vertex of zero
    stiffness (``RodGroup.unheld``) are no equilibrium at all and are not tested."""
    # the candidates in input strand order, whatever the groups (one device or several, or a vertex
    # count's strands built in several groups): the sample is the strands', not the grouping's
    tested = [(k, np.flatnonzero(~grp.unheld.any(axis=1))) for k, (_, _, grp) in enumerate(groups) if grp.N >= 2]
    group_of = np.concatenate([np.full(rows.size, k) for k, rows in tested] + [np.zeros(0, np.int64)])
    row_of = np.concatenate([rows for _, rows in tested] + [np.zeros(0, np.int64)])
    strand_of = np.concatenate([groups[k][1][rows] for k, rows in tested] + [np.zeros(0, np.int64)])
    by_strand = np.argsort(strand_of, kind="stable")
    group_of, row_of = group_of[by_strand], row_of[by_strand]
    total = group_of.size
    rng = np.random.default_rng(seed)
    order = rng.permutation(total) if total else np.zeros(0, np.int64)
    segments = np.array([g.N for _, _, g in groups], float)
    cost = segments[group_of[order]] ** 3 / 32.0 ** 3 if total else np.zeros(0)
    take = order[_within(cost, budget)] if cost.sum() > budget else order
    jobs = []                                                     # (group, rows) to test, a few MB each
    for k in np.unique(group_of[take]):
        grp = groups[k][2]
        rows = np.sort(row_of[take][group_of[take] == k])
        chunk = max(1, int(2.5e5 // grp.N ** 2))                 # about 70 MB of stiffness arrays at a time
        jobs += [(int(k), part) for part in np.array_split(rows, -(-rows.size // chunk))]
    margins = threaded_map(lambda job: stiffness_margins(groups[job[0]][2], job[1]), jobs)
    found = [(k, part[m < -1.0e-12]) for (k, part), m in zip(jobs, margins)]   # (group, rows) of the unstable
    flagged = np.concatenate([groups[k][1][rows] for k, rows in found] + [np.zeros(0, np.int64)])
    where = sorted((int(groups[k][1][r]), k, r) for k, rows in found for r in rows)   # in input strand order
    sample = np.sort(rng.choice(len(where), min(scale_sample, len(where)), replace=False)) if where else []
    picked = [where[i] for i in sample]                           # (strand, group, row), in strand order
    keys = sorted({k for _, k, _ in picked})
    per_group = {k: [(strand, r) for strand, kk, r in picked if kk == k] for k in keys}
    scales = threaded_map(lambda k: holding_scales(groups[k][2], np.array([r for _, r in per_group[k]])), keys)
    strands = [strand for k in keys for strand, _ in per_group[k]]   # the scales' order: back to strand order
    scales = np.concatenate([np.zeros(0)] + scales)[np.argsort(strands, kind="stable")]
    return np.sort(flagged), scales, len(take), total
