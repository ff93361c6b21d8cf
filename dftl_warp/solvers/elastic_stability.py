"""Is a strand's rest shape a stable equilibrium? (host side, numpy, float64)

Inverse statics (:mod:`.elastic_rest`) makes every authored shape an equilibrium under gravity, but
not every equilibrium is stable: hair standing up beyond its buckling length (a clamped column of
hair under its own weight buckles at ``L = 1.986 l_b``, Greenhill 1881, ``l_b = (EI / (rho A
g))^(1/3)``) is a broomstick balanced on end, and the smallest disturbance (round-off) makes it
fall. A game groom's gelled mohawk is such a shape for hair of human stiffness.

The test: the smallest eigenvalue of the stiffness at the rest shape, on the motions the solver
allows (the root and its clamp fixed, every segment's length kept): the bending matrix
``K = D^T W D`` (the solver's bands ``k0, k1, k2``) plus the geometric stiffness of the
inverse-statics tensions, ``T_k / l_k (I - e_k e_k^T)`` on each segment (negative under
compression). A negative eigenvalue is a direction in which the strand falls. The frames' twist
couplings are left out, so on curved strands the test may call a shape stable that is not; on
straight ones it is the discrete Greenhill problem (``tests/test_elastic_stability.py``: 1.986 l_b
within 1% at 32 segments).
"""

from __future__ import annotations

import numpy as np


def _constrained(grp, rows):
    """The bending and geometric stiffness of the strands ``rows`` of ``grp`` at the rest shape,
    on the motions the constraints allow: (S, 2N, 2N) each, and the bending bands' scale."""
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

    return project(Kb), project(Kg), np.abs(k0[:, 1:]).max(axis=1)


def stiffness_margins(grp, rows=None) -> np.ndarray:
    """Per strand of a :class:`~dftl_warp.solvers.elastic_rest.RodGroup` (its ``rows``, or all): the
    smallest eigenvalue of the constrained stiffness at the rest shape over the largest diagonal
    entry of the bending matrix (unitless). Below zero (beyond round-off): the rest shape is an
    unstable equilibrium."""
    rows = np.arange(grp.S) if rows is None else np.asarray(rows)
    if grp.N < 2:
        return np.ones(rows.size)
    Hb, Hg, scale = _constrained(grp, rows)
    return np.linalg.eigvalsh(Hb + Hg)[:, 0] / scale


def holding_scales(grp, rows=None) -> np.ndarray:
    """Per strand: the smallest factor on its bending stiffness (``bendStiffnessScale``) that makes
    its rest shape a stable equilibrium, the largest ``s`` with ``det(s Hb + Hg) = 0`` on the
    constrained motions (the bending part is positive definite: the root is clamped); 0 where
    tension alone holds the shape."""
    rows = np.arange(grp.S) if rows is None else np.asarray(rows)
    if grp.N < 2:
        return np.zeros(rows.size)
    Hb, Hg, _ = _constrained(grp, rows)
    L = np.linalg.cholesky(Hb)
    Li = np.linalg.inv(L)
    mu = np.linalg.eigvalsh(Li @ (-Hg) @ Li.transpose(0, 2, 1))[:, -1]
    return np.maximum(mu, 0.0)


def unstable_strands(groups, *, budget: int = 5000, seed: int = 0):
    """Strands whose rest shape is an unstable equilibrium, from the solver's rest groups ((count,
    input strand indices, RodGroup) triples). Only strands with a compressed segment can be
    unstable (bending and tension are stiffnesses that only hold), so only they are tested: all of
    them when that costs no more than ``budget`` strands of 32 segments (the test's cost grows as
    the cube of the segments: about 0.5 ms for 32 on one core), else a random sample within that
    budget. Returns (unstable input strand indices among those tested, their
    :func:`holding_scales`, strands tested, strands with a compressed segment)."""
    candidates = [(k, row) for k, (_, _, grp) in enumerate(groups) if grp.N >= 2
                  for row in np.flatnonzero((grp.T_rest[:, 1:] < 0).any(axis=1))]
    total = len(candidates)
    order = np.random.default_rng(seed).permutation(total) if total else np.zeros(0, np.int64)
    cost = np.array([groups[candidates[i][0]][2].N for i in order], float) ** 3 / 32.0 ** 3
    take = order[np.cumsum(cost) <= budget] if cost.sum() > budget else order
    picked = {}
    for i in take:
        k, row = candidates[i]
        picked.setdefault(k, []).append(row)
    flagged, scales = [np.zeros(0, np.int64)], [np.zeros(0)]
    for k, rows in sorted(picked.items()):
        _, strands, grp = groups[k]
        rows = np.sort(np.asarray(rows))
        chunk = max(1, int(1.0e6 // grp.N ** 2))                 # about 72 MB per stiffness array
        for part in np.array_split(rows, -(-rows.size // chunk)):
            bad = part[stiffness_margins(grp, part) < -1.0e-12]
            flagged.append(strands[bad])
            scales.append(holding_scales(grp, bad) if bad.size else np.zeros(0))
    flagged, scales = np.concatenate(flagged), np.concatenate(scales)
    order = np.argsort(flagged)
    return flagged[order], scales[order], len(take), total
