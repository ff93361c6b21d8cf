"""Binding of render strands to guides (numpy, float64, computed once at rest).

Each render strand gets its ``k`` nearest guides by root distance, radial-basis weights that sum to
one, and, for every vertex, its arc-length fraction and its rest offset in the guides' local frames
(:mod:`.frames`). ``frames="blend"`` (the default) keeps one offset per vertex, in the weighted blend
of the guides' frames at that fraction; ``frames="per-guide"`` keeps one offset per guide, each in
that guide's own frame, and blends the ``k`` predicted positions. A render strand that *is* a guide
gets weight 1 on itself and a zero offset, so guides are reproduced exactly.

:func:`deform_reference` applies a binding in numpy (float64); the device path is
:class:`~dftl_warp.guides.deform.GuideDeformer`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..core.layout import zero_length_segment
from .frames import arc_fractions, guide_frames, locate, normalize, sample

#: the most guides one render strand may follow (the device kernel unrolls up to this many)
MAX_K = 4
WEIGHTS = ("gaussian", "inverse-distance")
FRAMES = ("blend", "per-guide")
PARAMS = ("length", "fraction")
#: render vertices handled per numpy chunk while binding
CHUNK_VERTICES = 1 << 21


def check_strands(points, counts, points_name: str = "points", counts_name: str = "counts", least: int = 2):
    """(points (N, 3) float64, counts (S,) int64, starts (S,) int64), or ValueError naming the argument."""
    try:
        p = np.asarray(points, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"{points_name} must be an (N, 3) array of numbers") from None
    if p.ndim != 2 or p.shape[1] != 3:
        raise ValueError(f"{points_name} must have shape (N, 3), got {p.shape}")
    if not np.isfinite(p).all():
        raise ValueError(f"{points_name} holds a non-finite coordinate")
    c = np.asarray(counts)
    if c.ndim != 1 or (c.size and not np.issubdtype(c.dtype, np.integer)):
        raise ValueError(f"{counts_name} must be a 1-D array of integers")
    c = c.astype(np.int64)
    if c.size and c.min() < least:
        raise ValueError(f"{counts_name}: every strand needs at least {least} vertices (strand "
                         f"{int(np.argmin(c))} has {int(c.min())})")
    if int(c.sum()) != p.shape[0]:
        raise ValueError(f"{counts_name} sum to {int(c.sum())} vertices but {points_name} holds {p.shape[0]}")
    starts = np.zeros(c.size, dtype=np.int64)
    starts[1:] = np.cumsum(c)[:-1]
    return p, c, starts


def nearest(queries: np.ndarray, targets: np.ndarray, k: int, exclude_self: bool = False):
    """Indices (Q, k) and distances (Q, k) of the ``k`` nearest ``targets`` of each query, nearest first.

    Brute force in chunks (``Q x G`` distances, through a matrix product)."""
    Q, G = queries.shape[0], targets.shape[0]
    k = min(k, G - (1 if exclude_self else 0))
    idx = np.zeros((Q, k), dtype=np.int64)
    dist = np.zeros((Q, k))
    tn = np.sum(targets * targets, axis=1)
    step = max(1, (1 << 24) // max(G, 1))
    for a in range(0, Q, step):
        q = queries[a:a + step]
        d2 = np.sum(q * q, axis=1)[:, None] + tn[None, :] - 2.0 * (q @ targets.T)
        if exclude_self:
            d2[np.arange(q.shape[0]), np.arange(a, a + q.shape[0])] = np.inf
        part = np.argpartition(d2, k - 1, axis=1)[:, :k] if k < G else np.tile(np.arange(G), (q.shape[0], 1))
        # exact distances of the candidates (the product form loses digits near zero)
        dd = np.linalg.norm(q[:, None, :] - targets[part], axis=-1)
        order = np.argsort(dd, axis=1, kind="stable")
        idx[a:a + step] = np.take_along_axis(part, order, axis=1)
        dist[a:a + step] = np.take_along_axis(dd, order, axis=1)
    return idx, dist


def rbf_weights(dist: np.ndarray, k: int, kind: str) -> np.ndarray:
    """(R, k) weights from (R, k or k + 1) sorted root distances; each row sums to 1.

    The support radius ``h`` is the distance to the (k+1)-th nearest guide (twice the k-th one when
    there is none), so a guide's weight falls to zero as it leaves the k nearest: the binding is
    continuous across the groom. ``gaussian``: ``exp(-3 (d/h)^2) - exp(-3)``; ``inverse-distance``
    (Franke-Little): ``(1/d - 1/h)^2``, interpolating (a guide at distance 0 takes all the weight)."""
    d = dist[:, :k]
    h = dist[:, k] if dist.shape[1] > k else 2.0 * dist[:, k - 1]
    h = np.maximum(h, 1e-300)[:, None]
    if kind == "gaussian":
        w = np.maximum(np.exp(-3.0 * (d / h) ** 2) - np.exp(-3.0), 0.0)
    else:
        with np.errstate(divide="ignore"):
            inv = np.where(d > 0, 1.0 / np.maximum(d, 1e-300), np.inf)
        w = np.maximum(inv - 1.0 / h, 0.0) ** 2
        zero = d <= 0
        rows = zero.any(axis=1)
        w[rows] = zero[rows].astype(np.float64)
    total = w.sum(axis=1, keepdims=True)
    flat = total[:, 0] <= 0  # all k guides at the support radius (ties): equal weights
    w[flat] = 1.0
    return w / w.sum(axis=1, keepdims=True)


def reference_points(points, starts, counts):
    """(ref_guide, ref_vertex) of each guide: the root, among its 8 nearest guide roots, most
    perpendicular to its root tangent; a lone guide uses its own vertex farthest from that line."""
    G = counts.shape[0]
    roots = points[starts]
    t0 = normalize(points[starts + 1] - roots)
    ref_guide = np.full(G, -1, dtype=np.int64)
    ref_vertex = np.zeros(G, dtype=np.int64)
    if G > 1:
        idx, _ = nearest(roots, roots, 8, exclude_self=True)
        d = normalize(roots[idx] - roots[:, None, :])
        cos = np.abs(np.sum(d * t0[:, None, :], axis=-1))
        best = np.argmin(cos, axis=1)
        ok = cos[np.arange(G), best] < 0.999
        ref_guide[ok] = idx[np.arange(G), best][ok]
    for g in np.flatnonzero(ref_guide < 0):  # lone guide or all neighbours on its tangent line
        s, n = starts[g], counts[g]
        rel = points[s:s + n] - points[s]
        off = np.linalg.norm(rel - np.outer(rel @ t0[g], t0[g]), axis=1)
        j = int(np.argmax(off))
        if off[j] > 1e-9 * max(np.linalg.norm(rel, axis=1).max(), 1e-300):
            ref_guide[g], ref_vertex[g] = g, j
    return ref_guide, ref_vertex


@dataclass
class Binding:
    """Render strands bound to guides, host arrays (float64 where geometric)."""

    k: int
    weights_kind: str
    frames: str
    #: pull toward the primary guide, 0 (off) .. 1, growing from root to tip as ``t ** clump_shape``
    clump: float
    clump_shape: float
    guide_starts: np.ndarray  # (G,)
    guide_counts: np.ndarray  # (G,)
    guide_frac: np.ndarray  # (Mg,) rest arc parameter of every guide vertex: length (m) or fraction
    ref_guide: np.ndarray  # (G,)
    ref_vertex: np.ndarray  # (G,)
    render_starts: np.ndarray  # (R,)
    render_counts: np.ndarray  # (R,)
    guide_ids: np.ndarray  # (R, MAX_K) int, -1 past k; slot 0 is the primary (largest weight) guide
    weights: np.ndarray  # (R, MAX_K), 0 past k; rows sum to 1
    t: np.ndarray  # (Vr,) rest arc parameter (length or fraction, as guide_frac) of every render vertex
    offsets: np.ndarray  # (Vr, 3) for "blend", (Vr, k, 3) for "per-guide": (along T, N, B)
    render_guide: np.ndarray  # (R,) the guide a render strand is, else -1

    @property
    def num_guides(self) -> int:
        return int(self.guide_counts.shape[0])

    @property
    def num_render(self) -> int:
        return int(self.render_counts.shape[0])


def bind(guide_points, guide_counts, render_points, render_counts, *, k: int = 4, weights: str = "gaussian",
         frames: str = "blend", param: str = "length", clump: float = 0.0, clump_shape: float = 1.0,
         render_guides=None) -> Binding:
    """Bind render strands to guides at rest.

    Args:
        guide_points, guide_counts: the guides at rest, (M, 3) concatenated, root first; counts >= 2.
        render_points, render_counts: the render strands at rest, same conventions.
        k: guides per render strand, 1..4 and at most the number of guides.
        weights: ``"gaussian"`` or ``"inverse-distance"`` (:func:`rbf_weights`).
        frames: ``"blend"`` (one offset per vertex in the blended guide frame) or ``"per-guide"``.
        param: where a render vertex meets a guide: at the same arc ``"length"`` from the root (past
            the guide's tip: its tip, the offset covers the rest) or the same arc ``"fraction"``.
        clump: 0 (off) .. 1: render strands pulled toward their primary guide, ``clump * f ** clump_shape``
            of the way at the render vertex's arc fraction ``f``; changes the rest shape when > 0.
        render_guides: optional (R,) guide index of each render strand that is a guide (-1: none);
            by default a render strand equal to a guide (same count, same points) is that guide.

    Raises:
        ValueError naming the argument; a guide with two consecutive coincident points (no frame
        there) is refused (:func:`~dftl_warp.core.layout.zero_length_segment`).
    """
    gp, gc, gs = check_strands(guide_points, guide_counts, "guide_points", "guide_counts")
    rp, rc, rs = check_strands(render_points, render_counts, "render_points", "render_counts")
    G, R = gc.shape[0], rc.shape[0]
    if G == 0:
        raise ValueError("guide_counts is empty: no guides to bind to")
    found = zero_length_segment(gp, gc)   # no frame there: refused, not deformed off the rest shape
    if found is not None:
        raise ValueError(f"guide_points: guide {found[0]}: points {found[1]} and {found[1] + 1} coincide (a "
                         "zero-length segment): a guide needs non-zero segments to define its frames")
    if isinstance(k, (bool, np.bool_)) or not isinstance(k, (int, np.integer)) or not 1 <= k <= MAX_K:
        raise ValueError(f"k must be an integer in 1..{MAX_K}, got {k!r}")
    if k > G:
        raise ValueError(f"k = {k} is larger than the number of guides ({G})")
    if weights not in WEIGHTS:
        raise ValueError(f"weights must be one of {', '.join(WEIGHTS)}, got {weights!r}")
    if frames not in FRAMES:
        raise ValueError(f"frames must be one of {', '.join(FRAMES)}, got {frames!r}")
    if param not in PARAMS:
        raise ValueError(f"param must be one of {', '.join(PARAMS)}, got {param!r}")
    for name, value, lo, hi in (("clump", clump, 0.0, 1.0), ("clump_shape", clump_shape, 0.0, 100.0)):
        if not isinstance(value, (int, float, np.floating, np.integer)) or not lo <= float(value) <= hi:
            raise ValueError(f"{name} must be a number in [{lo}, {hi}], got {value!r}")

    ref_guide, ref_vertex = reference_points(gp, gs, gc)
    P, T, N = guide_frames(gp, gs, gc, ref_guide, ref_vertex)
    gfrac = arc_fractions(gp, gs, gc, normalise=param == "fraction")
    idx, dist = nearest(rp[rs], gp[gs], k + 1)
    w = rbf_weights(dist, k, weights)
    order = np.argsort(-w, axis=1, kind="stable")
    ids = np.full((R, MAX_K), -1, dtype=np.int64)
    wk = np.zeros((R, MAX_K))
    ids[:, :k] = np.take_along_axis(idx[:, :k], order, axis=1)
    wk[:, :k] = np.take_along_axis(w, order, axis=1)

    # render strands that are guides
    if render_guides is None:
        self_g = np.full(R, -1, dtype=np.int64)
        cand = np.flatnonzero(dist[:, 0] == 0.0)
        for r in cand:
            g = idx[r, 0]
            if rc[r] == gc[g] and np.array_equal(rp[rs[r]:rs[r] + rc[r]], gp[gs[g]:gs[g] + gc[g]]):
                self_g[r] = g
    else:
        self_g = np.asarray(render_guides, dtype=np.int64).reshape(-1)
        if self_g.shape[0] != R or (self_g >= G).any() or (self_g < -1).any():
            raise ValueError(f"render_guides must hold {R} guide indices in -1..{G - 1}")
        bad = np.flatnonzero((self_g >= 0) & (rc != gc[np.maximum(self_g, 0)]))
        if bad.size:
            raise ValueError(f"render_guides: render strand {bad[0]} has {rc[bad[0]]} vertices, "
                             f"its guide {self_g[bad[0]]} {gc[self_g[bad[0]]]}")

    t = arc_fractions(rp, rs, rc, normalise=param == "fraction")
    Vr = rp.shape[0]
    offsets = np.zeros((Vr, 3) if frames == "blend" else (Vr, k, 3))
    strand_of = np.repeat(np.arange(R), rc)
    for a in range(0, Vr, CHUNK_VERTICES):
        v = np.arange(a, min(Vr, a + CHUNK_VERTICES))
        s = strand_of[v]
        x = rp[v]
        if frames == "blend":
            pb, tb, nb = np.zeros_like(x), np.zeros_like(x), np.zeros_like(x)
        for slot in range(k):
            g = ids[s, slot]
            i, u = locate(gfrac, gs, gc, g, t[v])
            p, tg, ng, bg = sample(P, T, N, i, u)
            if frames == "blend":
                ww = wk[s, slot][:, None]
                pb += ww * p
                tb += ww * tg
                nb += ww * ng
            else:
                d = x - p
                offsets[v, slot] = np.stack([np.sum(d * tg, 1), np.sum(d * ng, 1), np.sum(d * bg, 1)], axis=1)
        if frames == "blend":
            tb, nb = blend_frame(tb, nb)
            d = x - pb
            offsets[v] = np.stack([np.sum(d * tb, 1), np.sum(d * nb, 1), np.sum(d * np.cross(tb, nb), 1)], axis=1)

    for r in np.flatnonzero(self_g >= 0):
        g = self_g[r]
        ids[r] = -1
        ids[r, 0] = g
        wk[r] = 0.0
        wk[r, 0] = 1.0
        t[rs[r]:rs[r] + rc[r]] = gfrac[gs[g]:gs[g] + gc[g]]
        offsets[rs[r]:rs[r] + rc[r]] = 0.0
    return Binding(k=int(k), weights_kind=weights, frames=frames, clump=float(clump), clump_shape=float(clump_shape),
                   guide_starts=gs, guide_counts=gc, guide_frac=gfrac, ref_guide=ref_guide, ref_vertex=ref_vertex,
                   render_starts=rs, render_counts=rc, guide_ids=ids, weights=wk, t=t, offsets=offsets,
                   render_guide=self_g)


def bind_groom(points, counts, guides, **options) -> Binding:
    """Bind every strand of a dense groom to the ``guides`` (strand indices) chosen from it; the
    guide strands are reproduced exactly. Options as :func:`bind`."""
    p, c, s = check_strands(points, counts)
    g = np.asarray(guides)
    if g.ndim != 1 or g.size == 0:
        raise ValueError("guides must be a non-empty 1-D array of strand indices")
    if not np.issubdtype(g.dtype, np.integer) or g.min() < 0 or g.max() >= c.shape[0] or np.unique(g).size != g.size:
        raise ValueError(f"guides must be distinct strand indices in 0..{c.shape[0] - 1}")
    gp = np.concatenate([p[s[i]:s[i] + c[i]] for i in g])
    render_guides = np.full(c.shape[0], -1, dtype=np.int64)
    render_guides[g] = np.arange(g.size)
    return bind(gp, c[g], p, c, render_guides=render_guides, **options)


def guide_points_of(points, counts, guides) -> tuple[np.ndarray, np.ndarray]:
    """(points, counts) of the strands ``guides`` of a groom, concatenated in that order."""
    p, c, s = check_strands(points, counts)
    g = np.asarray(guides, dtype=np.int64)
    return np.concatenate([p[s[i]:s[i] + c[i]] for i in g]), c[g]


def pin_roots(points: np.ndarray, binding: Binding, roots: np.ndarray) -> np.ndarray:
    """``points`` (Vr, 3), render points deformed by ``binding``, with every render strand that is not
    a guide translated so its root lands on ``roots[r]`` ((R, 3), same coordinates: where the scalp
    holds it). The guides' root frames turn with their free first segments, which would carry the
    render roots (rest offsets of up to a guide spacing) around the guides' roots; translating the
    whole strand keeps its deformed shape. Guide strands (already exact) are left as they are."""
    b = binding
    shift = np.asarray(roots, dtype=points.dtype) - points[b.render_starts]
    shift[b.render_guide >= 0] = 0.0
    return points + np.repeat(shift, b.render_counts, axis=0)


def blend_frame(t: np.ndarray, n: np.ndarray):
    """Orthonormal (T, N) from weighted sums of guide tangents and normals."""
    t = normalize(t)
    n = normalize(n - t * np.sum(n * t, axis=-1, keepdims=True))
    return t, n


def deform_reference(binding: Binding, guide_points) -> np.ndarray:
    """Render points (Vr, 3), float64, from the guides' current points (same layout as at binding)."""
    b = binding
    gp = np.asarray(guide_points, dtype=np.float64).reshape(-1, 3)
    P, T, N = guide_frames(gp, b.guide_starts, b.guide_counts, b.ref_guide, b.ref_vertex)
    R = b.num_render
    s = np.repeat(np.arange(R), b.render_counts)
    out = np.zeros((b.t.shape[0], 3))
    pb, tb, nb = np.zeros_like(out), np.zeros_like(out), np.zeros_like(out)
    primary = None
    for slot in range(b.k):
        g = b.guide_ids[s, slot]
        live = g >= 0
        gg = np.where(live, g, 0)
        i, u = locate(b.guide_frac, b.guide_starts, b.guide_counts, gg, b.t)
        p, tg, ng, bg = sample(P, T, N, i, u)
        ww = (b.weights[s, slot] * live)[:, None]
        if slot == 0:
            primary = p
        if b.frames == "blend":
            pb += ww * p
            tb += ww * tg
            nb += ww * ng
        else:
            o = b.offsets[:, slot]
            out += ww * (p + o[:, :1] * tg + o[:, 1:2] * ng + o[:, 2:] * bg)
    if b.frames == "blend":
        tb, nb = blend_frame(tb, nb)
        o = b.offsets
        out = pb + o[:, :1] * tb + o[:, 1:2] * nb + o[:, 2:] * np.cross(tb, nb)
    if b.clump > 0:
        last = b.t[b.render_starts + b.render_counts - 1][s]
        frac = np.divide(b.t, last, out=np.zeros_like(b.t), where=last > 0)
        out += (b.clump * frac ** b.clump_shape)[:, None] * (primary - out)
    return out
