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


def stiffness_margins(grp, rows=None) -> np.ndarray:
    """Per strand of a :class:`~dftl_warp.solvers.elastic_rest.RodGroup` (its ``rows``, or all): the
    smallest eigenvalue of the constrained stiffness at the rest shape over the largest diagonal
    entry of the bending matrix (unitless). Below zero (beyond round-off): the rest shape is an
    unstable equilibrium."""
    rows = np.arange(grp.S) if rows is None else np.asarray(rows)
    S, N = rows.size, grp.N
    if N < 2:
        return np.ones(S)
    k0, k1, k2 = grp.k0[rows], grp.k1[rows], grp.k2[rows]
    T, lengths = grp.T_rest[rows], grp.l[rows]
    e = grp.rest_directions[rows, 1:]                             # (S, N, 3) unit, segment k = 1..N
    eye = np.eye(3)
    K = np.zeros((S, N, N, 3, 3))                                 # free particles 1..N as rows 0..N-1
    kt = (T[:, 1:] / lengths[:, 1:N + 1])[..., None, None] * (eye - e[..., :, None] * e[..., None, :])
    for r in range(N):
        K[:, r, r] = k0[:, r + 1, None, None] * eye + kt[:, r]
        if r + 1 < N:
            K[:, r, r + 1] = K[:, r + 1, r] = k1[:, r + 1, None, None] * eye - kt[:, r + 1]
            K[:, r, r] += kt[:, r + 1]                            # segment r + 2 on its near end
        if r + 2 < N:
            K[:, r, r + 2] = K[:, r + 2, r] = k2[:, r + 1, None, None] * eye
    K = K.transpose(0, 1, 3, 2, 4).reshape(S, 3 * N, 3 * N)
    # the constraints e_k . (v_k - v_{k-1}) = 0 (v_0 = 0): their null space, from the SVD of J
    J = np.zeros((S, N, N, 3))
    for k in range(N):
        J[:, k, k] = e[:, k]
        if k:
            J[:, k, k - 1] = -e[:, k]
    _, _, vt = np.linalg.svd(J.reshape(S, N, 3 * N))
    basis = vt[:, N:].transpose(0, 2, 1)                         # (S, 3N, 2N)
    H = basis.transpose(0, 2, 1) @ K @ basis
    lowest = np.linalg.eigvalsh(0.5 * (H + H.transpose(0, 2, 1)))[:, 0]
    return lowest / np.abs(k0[:, 1:]).max(axis=1)


def unstable_strands(groups, *, sample: int = 5000, seed: int = 0, chunk: int = 1024):
    """Strands whose rest shape is an unstable equilibrium, from the solver's rest groups ((count,
    input strand indices, RodGroup) triples). Only strands with a compressed segment can be
    unstable (bending and tension are stiffnesses that only hold), so only they are tested; more
    than ``sample`` of them are tested on a random sample of that size. Returns (unstable input
    strand indices among those tested, strands tested, strands with a compressed segment)."""
    compressed = []
    for _, strands, grp in groups:
        if grp.N < 2:
            continue
        rows = np.flatnonzero((grp.T_rest[:, 1:] < 0).any(axis=1))
        compressed += [(grp, strands, r) for r in np.array_split(rows, max(1, -(-rows.size // chunk))) if r.size]
    total = sum(r.size for _, _, r in compressed)
    keep = None
    if total > sample:
        keep = np.zeros(total, bool)
        keep[np.random.default_rng(seed).choice(total, sample, replace=False)] = True
    unstable, tested, offset = [], 0, 0
    for grp, strands, rows in compressed:
        if keep is not None:
            rows, offset = rows[keep[offset:offset + rows.size]], offset + rows.size
        if rows.size == 0:
            continue
        margins = stiffness_margins(grp, rows)
        unstable.append(strands[rows[margins < -1.0e-12]])
        tested += rows.size
    flagged = np.concatenate(unstable) if unstable else np.zeros(0, np.int64)
    return np.sort(flagged), tested, total
