"""Render strands deformed by guides, float32 (mirrors :mod:`dftl_warp.guides.frames` and
:func:`dftl_warp.guides.binding.deform_reference`).

:data:`guide_frames` (one thread per guide) reads each guide's current points through any layout
(``positions[base[g] + i * stride[g]]``) and writes compact positions, tangents and normals;
:func:`deform_kernel` (one thread per render strand) samples them at each render vertex's arc
fraction and applies the rest offsets.
"""

import functools

import warp as wp

U_TURN = wp.constant(1.0e-6)


@wp.func
def guide_point(positions: wp.array(dtype=wp.vec3), base: wp.array(dtype=wp.int32),
                stride: wp.array(dtype=wp.int32), g: int, i: int):
    return positions[base[g] + i * stride[g]]


@wp.func
def fallback_axis(t: wp.vec3):
    ax = wp.abs(t[0])
    ay = wp.abs(t[1])
    az = wp.abs(t[2])
    e = wp.vec3(1.0, 0.0, 0.0)
    if ay < ax and ay <= az:
        e = wp.vec3(0.0, 1.0, 0.0)
    elif az < ax and az < ay:
        e = wp.vec3(0.0, 0.0, 1.0)
    return e


@wp.func
def perpendicular(d: wp.vec3, t: wp.vec3):
    r = d - t * wp.dot(d, t)
    n = wp.length(r)
    out = wp.vec3(0.0, 0.0, 0.0)
    if n > 0.0:
        out = r / n
    return out


@wp.func
def transport(n: wp.vec3, a: wp.vec3, b: wp.vec3):
    """``n`` carried by the smallest rotation taking unit ``a`` to unit ``b``, made perpendicular to ``b``."""
    v = wp.cross(a, b)
    c = wp.dot(a, b)
    r = n
    if 1.0 + c > U_TURN:
        r = n * c + wp.cross(v, n) + v * (wp.dot(v, n) / (1.0 + c))
    return perpendicular(r, b)


@wp.func
def unit(v: wp.vec3):
    n = wp.length(v)
    out = wp.vec3(0.0, 0.0, 0.0)
    if n > 0.0:
        out = v / n
    return out


@wp.kernel(enable_backward=False, module="unique")
def guide_frames(
    positions: wp.array(dtype=wp.vec3),
    base: wp.array(dtype=wp.int32),
    stride: wp.array(dtype=wp.int32),
    start: wp.array(dtype=wp.int32),
    count: wp.array(dtype=wp.int32),
    ref_guide: wp.array(dtype=wp.int32),
    ref_vertex: wp.array(dtype=wp.int32),
    P: wp.array(dtype=wp.vec3),
    T: wp.array(dtype=wp.vec3),
    N: wp.array(dtype=wp.vec3),
):
    g = wp.tid()
    s = start[g]
    n = count[g]
    p0 = guide_point(positions, base, stride, g, 0)
    p1 = guide_point(positions, base, stride, g, 1)
    seg = unit(p1 - p0)
    t_prev = seg
    rg = ref_guide[g]
    d = fallback_axis(t_prev)
    if rg >= 0:
        d = guide_point(positions, base, stride, rg, ref_vertex[g]) - p0
    n_prev = perpendicular(d, t_prev)
    if wp.length(n_prev) == 0.0:
        n_prev = perpendicular(fallback_axis(t_prev), t_prev)
    P[s] = p0
    T[s] = t_prev
    N[s] = n_prev
    p = p1
    for i in range(1, n):
        ti = seg
        if i < n - 1:
            q = guide_point(positions, base, stride, g, i + 1)
            nxt = unit(q - p)
            both = unit(seg + nxt)
            if wp.length(both) == 0.0:
                both = nxt
            ti = both
            seg = nxt
            P[s + i] = p
            p = q
        else:
            P[s + i] = p
        n_prev = transport(n_prev, t_prev, ti)
        t_prev = ti
        T[s + i] = ti
        N[s + i] = n_prev


@wp.func
def locate(frac: wp.array(dtype=float), s: int, n: int, t: float):
    """First vertex (global index) of the segment holding arc fraction ``t``, and the fraction ``u``."""
    lo = s
    hi = s + n - 2
    while lo < hi:
        mid = (lo + hi + 1) // 2
        if frac[mid] <= t:
            lo = mid
        else:
            hi = mid - 1
    a0 = frac[lo]
    span = frac[lo + 1] - a0
    u = float(0.0)
    if span > 0.0:
        u = wp.clamp((t - a0) / span, 0.0, 1.0)
    return lo, u


@functools.cache
def deform_kernel(per_guide: bool, clumped: bool):
    """Kernel: render points (flat, input order) from the compact guide frames.

    ``per_guide``: offsets are ``k`` per vertex (``offsets[v * k + slot]``), each in its guide's frame,
    and the ``k`` predictions are blended; else one offset per vertex, in the blended frame."""

    @wp.kernel(enable_backward=False, module="unique")
    def deform(
        P: wp.array(dtype=wp.vec3),
        T: wp.array(dtype=wp.vec3),
        N: wp.array(dtype=wp.vec3),
        guide_start: wp.array(dtype=wp.int32),
        guide_count: wp.array(dtype=wp.int32),
        guide_frac: wp.array(dtype=float),
        render_start: wp.array(dtype=wp.int32),
        render_count: wp.array(dtype=wp.int32),
        ids: wp.array(dtype=wp.vec4i),
        weights: wp.array(dtype=wp.vec4),
        t: wp.array(dtype=float),
        offsets: wp.array(dtype=wp.vec3),
        k: int,
        clump: float,
        clump_shape: float,
        out: wp.array(dtype=wp.vec3),
    ):
        r = wp.tid()
        s = render_start[r]
        gid = ids[r]
        w = weights[r]
        n_r = render_count[r]
        t_last = t[s + n_r - 1]
        for j in range(n_r):
            v = s + j
            tj = t[v]
            pb = wp.vec3(0.0, 0.0, 0.0)
            tb = wp.vec3(0.0, 0.0, 0.0)
            nb = wp.vec3(0.0, 0.0, 0.0)
            x = wp.vec3(0.0, 0.0, 0.0)
            primary = wp.vec3(0.0, 0.0, 0.0)
            for slot in range(k):
                g = gid[slot]
                if g >= 0:
                    gs = guide_start[g]
                    i, u = locate(guide_frac, gs, guide_count[g], tj)
                    p = (1.0 - u) * P[i] + u * P[i + 1]
                    tg = unit((1.0 - u) * T[i] + u * T[i + 1])
                    ng = perpendicular((1.0 - u) * N[i] + u * N[i + 1], tg)
                    if slot == 0:
                        primary = p
                    ww = w[slot]
                    if wp.static(per_guide):
                        o = offsets[v * k + slot]
                        x = x + ww * (p + o[0] * tg + o[1] * ng + o[2] * wp.cross(tg, ng))
                    else:
                        pb = pb + ww * p
                        tb = tb + ww * tg
                        nb = nb + ww * ng
            if wp.static(not per_guide):
                tb = unit(tb)
                nb = perpendicular(nb, tb)
                o = offsets[v]
                x = pb + o[0] * tb + o[1] * nb + o[2] * wp.cross(tb, nb)
            if wp.static(clumped):
                f = float(0.0)
                if t_last > 0.0:
                    f = tj / t_last
                x = x + (clump * wp.pow(f, clump_shape)) * (primary - x)
            out[v] = x

    return deform
