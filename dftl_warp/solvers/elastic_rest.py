"""Host-side (numpy, float64) precomputation of the elastic-rod solver (:mod:`.elastic`).

Everything here is done once per solver, per group of strands with equal vertex count, vectorised
over the group. The formulation is scheme K (``/work/scratch/rods2/README.md``); per strand of
``N + 1`` particles (particle 0 the kinematic root) and a kinematic *clamp ghost* ``x_{-1}`` behind
the root:

- masses ``m_i = rho pi r_i^2 (l_i + l_{i+1}) / 2`` (the tip: half its segment);
- the discrete curvature ``(Dx)_j = -(x_j - x_{j-1}) / l_j + (x_{j+1} - x_j) / l_{j+1}``,
  ``j = 0..N-1``, ``l_0 = l_1`` the ghost segment;
- bending weights ``W_j = E pi r_j^4 / 4 / ell_j`` (``ell_j`` the Voronoi length, ``ell_0 = l_1 / 2``)
  and the pentadiagonal ``K = D^T W D`` as three bands ``k0, k1, k2`` per particle;
- twist couplings ``G_j = G pi r_j^4 / 2 / (2 ell_j)`` between consecutive frames;
- rest curvature vectors ``b_j`` and rest relative rotations ``Qb_j``; with ``inverse_statics`` they
  are chosen so that the authored shape with all frames at identity is an exact equilibrium under
  gravity (tensions ``T`` and bending moments ``rho`` solved tip -> root; the frame torques they
  leave are carried by the twist couplings, whose ``G_j`` is raised where ``sin(theta) > 1/2``
  would be needed).

Energy: ``E_b = sum_j W_j/2 |(Dx)_j - F_j b_j|^2 + sum_j G_j (3 - tr(F_j^T F_{j-1} Qb_j))``,
``F_{-1}`` the root frame. Units are those of the inputs (SI, or consistent stage units).
"""

from __future__ import annotations

import numpy as np

from ..core.layout import strand_offsets


def skew(a):
    z = np.zeros(a.shape[:-1])
    return np.stack([np.stack([z, -a[..., 2], a[..., 1]], -1),
                     np.stack([a[..., 2], z, -a[..., 0]], -1),
                     np.stack([-a[..., 1], a[..., 0], z], -1)], -2)


def expm_so3(w):
    """Rotation matrices exp([w]x) (Rodrigues), batched."""
    th = np.linalg.norm(w, axis=-1)[..., None, None]
    K = skew(w)
    safe = np.where(th > 0, th, 1.0)
    s = np.where(th > 1e-12, np.sin(th) / safe, 1.0)
    c = np.where(th > 1e-12, (1 - np.cos(th)) / safe ** 2, 0.5)
    # K K = w w^T - |w|^2 I, without a batched 3x3 product (a third of a large groom's set-up)
    KK = w[..., :, None] * w[..., None, :] - (th * th) * np.eye(3)
    return np.eye(3) + s * K + c * KK


def mat_to_quat(R):
    """Unit quaternions (x, y, z, w) of rotation matrices (..., 3, 3) (Shepperd's method)."""
    R = np.asarray(R, float)
    q = np.empty(R.shape[:-2] + (4,))
    tr = np.trace(R, axis1=-2, axis2=-1)
    d = np.stack([R[..., 0, 0], R[..., 1, 1], R[..., 2, 2]], -1)
    c = np.argmax(np.concatenate([tr[..., None], d], -1), -1)
    for case in range(4):
        sel = c == case
        if not sel.any():
            continue
        r = R[sel]
        if case == 0:
            s = 2 * np.sqrt(1 + np.trace(r, axis1=-2, axis2=-1))
            qq = np.stack([(r[:, 2, 1] - r[:, 1, 2]) / s, (r[:, 0, 2] - r[:, 2, 0]) / s,
                           (r[:, 1, 0] - r[:, 0, 1]) / s, 0.25 * s], -1)
        else:
            i = case - 1
            j, k = (i + 1) % 3, (i + 2) % 3
            s = 2 * np.sqrt(1 + r[:, i, i] - r[:, j, j] - r[:, k, k])
            qq = np.empty((r.shape[0], 4))
            qq[:, i] = 0.25 * s
            qq[:, j] = (r[:, j, i] + r[:, i, j]) / s
            qq[:, k] = (r[:, k, i] + r[:, i, k]) / s
            qq[:, 3] = (r[:, k, j] - r[:, j, k]) / s
        q[sel] = qq
    return q / np.linalg.norm(q, axis=-1, keepdims=True)


def quat_to_mat(q):
    x, y, z, w = np.moveaxis(np.asarray(q, float), -1, 0)
    return np.stack([np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)], -1),
                     np.stack([2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)], -1),
                     np.stack([2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)], -1)], -2)


def rotation_between(a, b):
    """The minimal rotation matrices taking unit vectors ``a`` to ``b`` (batched); the kernel's
    root frame (:mod:`dftl_warp.kernels.solvers.elastic`)."""
    a = a / np.linalg.norm(a, axis=-1, keepdims=True)
    b = b / np.linalg.norm(b, axis=-1, keepdims=True)
    c = np.cross(a, b)
    d = np.sum(a * b, -1)
    q = np.concatenate([c, (1.0 + d)[..., None]], -1)
    flip = (1.0 + d) < 1e-12                # antiparallel: a half turn about any normal of a
    if flip.any():
        n = np.cross(a[flip], np.where(np.abs(a[flip, :1]) < 0.9, [[1.0, 0, 0]], [[0, 1.0, 0]]))
        q[flip] = np.concatenate([n, np.zeros((n.shape[0], 1))], -1)
    return quat_to_mat(q / np.linalg.norm(q, axis=-1, keepdims=True))


class RodGroup:
    """Rest data of ``S`` strands of ``N + 1`` particles: ``rest`` (S, N+1, 3), ``radius`` (S, N+1)."""

    def __init__(self, rest, radius, *, E, G, rho, gravity, inverse_statics, bend_scale=None):
        rest = np.asarray(rest, float)
        S, n1, _ = rest.shape
        N = n1 - 1
        self.S, self.N = S, N
        g = np.asarray(gravity, float)
        r = np.broadcast_to(np.asarray(radius, float), (S, n1))
        #: the rest shape (S, N+1, 3), hair radii (S, N+1) and what else built the group (:meth:`scaled`)
        self.rest, self.radius = rest, r
        self._material = dict(E=E, G=G, rho=rho, gravity=gravity, inverse_statics=inverse_statics)
        self._bend_scale = None if bend_scale is None else np.broadcast_to(np.asarray(bend_scale, float), (S, n1))
        seg = rest[:, 1:] - rest[:, :-1]
        lseg = np.linalg.norm(seg, axis=-1)
        l = np.zeros((S, n1 + 1))
        l[:, 1:n1] = lseg
        l[:, 0] = lseg[:, 0]
        self.l = l                                               # l[0]: the ghost segment
        A = np.pi * r ** 2
        m = np.zeros((S, n1))
        m[:, 1:N] = rho * A[:, 1:N] * 0.5 * (lseg[:, :-1] + lseg[:, 1:])
        m[:, N] = rho * A[:, N] * 0.5 * lseg[:, -1]
        self.m = m                                               # m[0] unused (kinematic root)
        self.alpha = 1.0 / l[:, 0:N]
        self.gamma = 1.0 / l[:, 1:N + 1]
        ell = 0.5 * (l[:, 0:N] + l[:, 1:N + 1])
        ell[:, 0] = 0.5 * l[:, 1]
        self.W = E * np.pi * r[:, :N] ** 4 / 4.0 / ell
        if bend_scale is not None:                               # a stiffness ramp: a factor on E*I per vertex
            self.W = self.W * np.broadcast_to(np.asarray(bend_scale, float), (S, n1))[:, :N]
        Gj = G * np.pi * r[:, :N] ** 4 / 2.0 / (2.0 * ell)
        e1 = seg[:, 0] / lseg[:, 0:1]
        self.d0 = e1                                             # authored clamp direction (ghost -> root)
        self.ghost = rest[:, 0] - l[:, 0:1] * e1                 # authored ghost points
        Dx = self.apply_D(rest, self.ghost)
        T, rho_ = self.statics(rest, self.ghost, g)
        self.b, rho_ = self.rest_curvature(Dx, rho_, inverse_statics)
        self.T_rest = T
        #: unit segment directions of the rest shape (S, N+1, 3; index 0 the ghost segment)
        self.rest_directions = self.directions(rest, self.ghost)
        # frame inverse statics: the torques g_j = -b_j x rho_j are carried by the twist couplings
        gb = -np.cross(self.b, rho_)
        mom = np.cumsum(gb[:, ::-1], axis=1)[:, ::-1]            # m_j = sum_{k >= j} g_k
        mn = np.linalg.norm(mom, axis=-1)
        self.G_raise = np.maximum(1.0, mn / (2 * Gj * 0.5))
        self.G = Gj * self.G_raise
        sn = mn / (2 * self.G)
        th = np.arcsin(sn)
        ax = mom / np.where(sn > 0, mn, 1)[..., None]
        self.Qb = expm_so3(ax * th[..., None])                   # (S, N, 3, 3)
        self.curved = np.any(np.abs(self.b) > 0, axis=(1, 2))     # per strand
        self.k0, self.k1, self.k2 = self.bands()

    def rest_curvature(self, Dx, rho_, inverse_statics: bool):
        """Rest curvatures ``b`` (S, N, 3) and the bending moments ``W (Dx - b)`` they leave in the
        rest shape: with ``inverse_statics``, ``b = Dx - rho / W`` and the moments are the statics'
        ``rho``, which hold the authored shape; without, ``b = Dx`` and no moment.

        A vertex of zero bending stiffness (``bend_scale`` 0) is a hinge: it carries no moment
        whatever its ``b``, so its ``b`` is the authored curvature and its moment 0. Where the shape
        needs a moment there (more than 1e-9 of the strand's weight, N), it is not held: the hair
        bends at that vertex (:attr:`unheld`, (S, N))."""
        hinge = self.W <= 0.0
        need = np.linalg.norm(rho_, axis=-1)
        weight = np.sum(self.m, axis=1, keepdims=True) * np.linalg.norm(self._material["gravity"])
        #: vertices of zero stiffness whose moment the authored shape needs (inverse statics)
        self.unheld = hinge & (need > 1e-9 * weight) if inverse_statics else np.zeros_like(hinge)
        if not inverse_statics:
            return Dx.copy(), np.zeros_like(rho_)
        b = Dx - rho_ / np.where(hinge, 1.0, self.W)[..., None]
        return np.where(hinge[..., None], Dx, b), np.where(hinge[..., None], 0.0, rho_)

    def scaled(self, rows, factors) -> "RodGroup":
        """The group of strands ``rows`` with their bending stiffness multiplied by ``factors`` (one
        per row): what ``primvars:dftl:bendStiffnessScale`` times ``factors`` would build."""
        rows = np.asarray(rows)
        base = np.ones((rows.size, self.N + 1)) if self._bend_scale is None else self._bend_scale[rows]
        return RodGroup(self.rest[rows], self.radius[rows], bend_scale=base * np.asarray(factors, float)[:, None],
                        **self._material)

    def apply_D(self, x, xg):
        N = self.N
        xm = np.concatenate([xg[:, None], x[:, :-1]], axis=1)
        return (-self.alpha[..., None] * (x[:, :N] - xm[:, :N])
                + self.gamma[..., None] * (x[:, 1:] - x[:, :N]))

    def directions(self, x, xg):
        e = np.empty((self.S, self.N + 1, 3))
        e[:, 0] = (x[:, 0] - xg) / self.l[:, 0:1]
        e[:, 1:] = (x[:, 1:] - x[:, :-1]) / self.l[:, 1:self.N + 1, None]
        return e

    def statics(self, x, xg, g):
        """Tensions T (S, N+1) and bending moments rho (S, N, 3) holding ``x`` still under ``g``."""
        S, N = self.S, self.N
        e = self.directions(x, xg)
        T = np.zeros((S, N + 2))
        load = np.zeros((S, 3))
        for i in range(N, 0, -1):
            load = load + self.m[:, i:i + 1] * g
            T[:, i] = np.sum(load * e[:, i], axis=-1)
        rho_ = np.zeros((S, N + 2, 3))
        al = np.concatenate([self.alpha, np.zeros((S, 2))], axis=1)
        ga = np.concatenate([self.gamma, np.zeros((S, 2))], axis=1)
        for i in range(N, 0, -1):
            e_next = e[:, i + 1] if i < N else np.zeros((S, 3))
            rhs = (self.m[:, i:i + 1] * g - T[:, i:i + 1] * e[:, i] + T[:, i + 1:i + 2] * e_next
                   + (al[:, i:i + 1] + ga[:, i:i + 1]) * rho_[:, i] - al[:, i + 1:i + 2] * rho_[:, i + 1])
            rho_[:, i - 1] = rhs / ga[:, i - 1:i]
        return T[:, :N + 1], rho_[:, :N]

    def bands(self):
        S, N = self.S, self.N
        W = np.zeros((S, N + 3)); W[:, :N] = self.W
        al = np.zeros((S, N + 3)); al[:, :N] = self.alpha
        ga = np.zeros((S, N + 3)); ga[:, :N] = self.gamma
        k0 = np.zeros((S, N + 1)); k1 = np.zeros((S, N + 1)); k2 = np.zeros((S, N + 1))
        for i in range(1, N + 1):
            k0[:, i] = (ga[:, i - 1] ** 2 * W[:, i - 1] + (al[:, i] + ga[:, i]) ** 2 * W[:, i]
                        + al[:, i + 1] ** 2 * W[:, i + 1])
            k1[:, i] = (-(al[:, i] + ga[:, i]) * ga[:, i] * W[:, i]
                        - al[:, i + 1] * (al[:, i + 1] + ga[:, i + 1]) * W[:, i + 1])
            k2[:, i] = al[:, i + 1] * ga[:, i + 1] * W[:, i + 1]
        return k0, k1, k2

    def energy(self, x, v, F, xg, g, clamp_rotation=None, twist_mask=None):
        """Kinetic + gravitational + elastic energy per strand (J). The potential energy is
        measured from the strand hanging straight down from its root (``|g| s_i - g.(x_i - x_0)``,
        ``s_i`` the arc length), so it is >= 0. ``clamp_rotation`` (S, 3, 3): the clamp's turn from
        its authored pose, which turns the root frame as in the kernel (identity when None);
        ``twist_mask`` (S,): the strands whose twist energy counts (all when None)."""
        m = self.m[:, 1:]
        ke = 0.5 * np.sum(m * np.sum(v[:, 1:] ** 2, -1), -1)
        s_along = np.cumsum(self.l[:, 1:self.N + 1], axis=1)
        pe = np.sum(m * (np.linalg.norm(g) * s_along - np.sum(g * (x[:, 1:] - x[:, :1]), -1)), -1)
        if clamp_rotation is None:
            R_root = rotation_between(self.d0, x[:, 0] - xg)
        else:
            d0 = np.einsum("sab,sb->sa", clamp_rotation, self.d0)
            R_root = np.einsum("sab,sbc->sac", rotation_between(d0, x[:, 0] - xg), clamp_rotation)
        r = self.apply_D(x, xg) - np.einsum('sjab,sjb->sja', F, self.b)
        eb = 0.5 * np.sum(self.W * np.sum(r * r, -1), -1)
        Fprev = np.concatenate([R_root[:, None], F[:, :-1]], axis=1)
        rel = np.einsum('sjba,sjbc,sjcd->sjad', F, Fprev, self.Qb)
        G = self.G if twist_mask is None else np.where(np.asarray(twist_mask)[:, None], self.G, 0.0)
        et = np.sum(G * (3 - np.trace(rel, axis1=-2, axis2=-1)), -1)
        return ke + pe + eb + et


#: strands per :class:`RodGroup` of :func:`build`: a groom's strands of one vertex count are cut into
#: groups of this many, built on threads (numpy releases the GIL in its array loops; each group's
#: values are those of one large group, strand by strand)
CHUNK_STRANDS = 16384


def threaded_map(fn, items):
    """``[fn(x) for x in items]``, on a thread per CPU core when there are several items."""
    items = list(items)
    if len(items) < 2:
        return [fn(x) for x in items]
    import os
    from concurrent.futures import ThreadPoolExecutor

    with ThreadPoolExecutor(max_workers=min(len(items), os.cpu_count() or 1)) as pool:
        return list(pool.map(fn, items))


#: per-particle model arrays (slot order) the kernel reads, and their widths
PARTICLE_FIELDS = {"length": 1, "mass": 1, "bend": 1, "twist": 1, "k0": 1, "k1": 1, "k2": 1,
                   "curvature": 3, "rest_rotation": 4}


def build(points, counts, slot_of_point, strand_order, num_slots, radius, *, E, G, rho, gravity,
          inverse_statics, stiffness_scale=None):
    """Slot-ordered model arrays (float64 numpy, :data:`PARTICLE_FIELDS`), per device strand data
    (``ghost``, ``d0``, ``curved``, ``tension``: the inverse-statics tensions per slot) and the
    groups (count, input strand indices, :class:`RodGroup`) for the host-side energy.

    ``points`` (P, 3) float64 in input order (device coordinates), ``radius`` (P,)."""
    counts = np.asarray(counts, np.int64)
    starts = strand_offsets(counts)
    out = {k: np.zeros((num_slots, w) if w > 1 else num_slots) for k, w in PARTICLE_FIELDS.items()}
    out["rest_rotation"][:, 3] = 1.0
    tension = np.zeros(num_slots)
    S = counts.shape[0]
    ghost = np.zeros((S, 3)); d0 = np.zeros((S, 3)); d0[:, 0] = 1.0
    curved = np.zeros(S, np.int32)
    groups = []
    for n in np.unique(counts):
        strands = np.flatnonzero(counts == n)
        idx = starts[strands][:, None] + np.arange(n)[None]          # (S_g, n) point indices
        if n < 2:
            ghost[strands] = points[idx[:, 0]] - np.array([1.0, 0, 0])
            continue
        rest = points[idx]
        seg = np.linalg.norm(np.diff(rest, axis=1), axis=-1)
        if np.any(seg <= 0.0):
            s, i = np.argwhere(seg <= 0.0)[0]
            s, i = int(strands[s]), int(i)
            raise ValueError(f"strand {s} of the model, segment {i}: points {i} and {i + 1} coincide (a zero-length "
                             "segment); the elastic solver needs non-zero rest lengths: remove the coincident "
                             "points, or use --solver dftl, which simulates them")
        def rods(piece, rest=rest, idx=idx):
            grp = RodGroup(rest[piece], radius[idx[piece]], E=E, G=G, rho=rho, gravity=gravity,
                           inverse_statics=inverse_statics,
                           bend_scale=None if stiffness_scale is None else stiffness_scale[idx[piece]])
            return grp, mat_to_quat(grp.Qb)

        pieces = [slice(a, a + CHUNK_STRANDS) for a in range(0, strands.size, CHUNK_STRANDS)]
        for piece, (grp, quat) in zip(pieces, threaded_map(rods, pieces)):
            rows = strands[piece]
            groups.append((int(n), rows, grp))
            slots = slot_of_point[idx[piece]]                         # (S_g, n)
            N = n - 1
            out["length"][slots] = grp.l[:, :n]
            out["mass"][slots] = grp.m
            out["bend"][slots[:, :N]] = grp.W
            out["twist"][slots[:, :N]] = grp.G
            out["k0"][slots] = grp.k0
            out["k1"][slots] = grp.k1
            out["k2"][slots] = grp.k2
            out["curvature"][slots[:, :N]] = grp.b
            out["rest_rotation"][slots[:, :N]] = quat
            tension[slots] = grp.T_rest
            ghost[rows] = grp.ghost
            d0[rows] = grp.d0
            curved[rows] = grp.curved
    # per device strand
    order = np.asarray(strand_order)
    return out, dict(ghost=ghost[order], d0=d0[order], curved=curved[order], tension=tension), groups
