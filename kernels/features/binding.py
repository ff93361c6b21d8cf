"""Roots bound to a deforming triangle mesh: each root is a barycentric point on one triangle."""


import functools

import warp as wp


@functools.cache
def bind_roots_kernel(scalar):
    """Kernel: root targets of each device strand from the mesh points at frame start and end.

    ``root = w0 p[i0] + w1 p[i1] + w2 p[i2]`` with the strand's triangle ``(i0, i1, i2)`` and
    barycentric weights ``w``; points and roots in device coordinates (m). The sums are linear,
    so the same kernel gives the roots' velocities (m/s) from the points' velocities."""
    vec3 = wp.types.vector(3, scalar)

    @wp.kernel(enable_backward=False, module="unique")
    def bind_roots(
        triangle: wp.array(dtype=wp.vec3i),
        weights: wp.array(dtype=vec3),
        points_start: wp.array(dtype=vec3),
        points_end: wp.array(dtype=vec3),
        root_start: wp.array(dtype=vec3),
        root_end: wp.array(dtype=vec3),
    ):
        s = wp.tid()
        t = triangle[s]
        w = weights[s]
        root_start[s] = w[0] * points_start[t[0]] + w[1] * points_start[t[1]] + w[2] * points_start[t[2]]
        root_end[s] = w[0] * points_end[t[0]] + w[1] * points_end[t[1]] + w[2] * points_end[t[2]]

    return bind_roots


@wp.kernel(enable_backward=False, module="unique")
def closest_face(mesh: wp.uint64, points: wp.array(dtype=wp.vec3), face: wp.array(dtype=wp.int32),
                 bary: wp.array(dtype=wp.vec3)):
    """Closest triangle of ``mesh`` to each point, with the barycentric weights of the closest point."""
    i = wp.tid()
    q = wp.mesh_query_point_no_sign(mesh, points[i], 1.0e30)
    if q.result:
        face[i] = q.face
        bary[i] = wp.vec3(q.u, q.v, 1.0 - q.u - q.v)
    else:
        face[i] = -1


@functools.cache
def bind_clamps_kernel(scalar):
    """Kernel: the elastic solver's clamp ghosts of each device strand at frame start and end, turned
    with the strand's bound triangle, their path's deviations, and the triangle's rotations.

    The triangle's frame is ``F = [t, n x t, n]`` (columns): ``t`` its edge 0 (point 0 to point 1)
    and ``n`` its unit normal ``(p1 - p0) x (p2 - p0)``, normalised. Its rotation from the rest mesh
    is ``R = F F_rest^T`` (identity where either triangle is degenerate: zero edge 0 or zero area),
    and the ghost is ``root + R offset`` with ``offset`` the authored ghost minus the authored root
    (m, device coordinates). With ``frame_duration`` ``T > 0`` (s) the ghost's velocity at each end
    is its exact rate for the mesh points' velocities there, ``v_root + dF F_rest^T offset``, and
    the deviations are ``T v - (ghost_end - ghost_start)`` (:mod:`dftl_warp.kernels.core.root_path`);
    ``T = 0`` gives zero deviations (the linear path)."""
    vec3 = wp.types.vector(3, scalar)
    mat33 = wp.types.matrix((3, 3), scalar)
    zero = scalar(0.0)

    @wp.func
    def frame_of(p0: vec3, p1: vec3, p2: vec3):
        """The triangle's frame [t, n x t, n] (zero where it is degenerate)."""
        e0 = p1 - p0
        c = wp.cross(e0, p2 - p0)
        if wp.length(e0) == zero or wp.length(c) == zero:
            return mat33()
        t = wp.normalize(e0)
        n = wp.normalize(c)
        b = wp.cross(n, t)
        return mat33(t[0], b[0], n[0], t[1], b[1], n[1], t[2], b[2], n[2])

    @wp.func
    def frame_rate(p0: vec3, p1: vec3, p2: vec3, u0: vec3, u1: vec3, u2: vec3):
        """d/dt of :func:`frame_of` for the points' velocities ``u`` (1/s; zero where degenerate)."""
        e0 = p1 - p0
        e1 = p2 - p0
        c = wp.cross(e0, e1)
        le = wp.length(e0)
        lc = wp.length(c)
        if le == zero or lc == zero:
            return mat33()
        t = e0 / le
        n = c / lc
        de = u1 - u0
        dc = wp.cross(de, e1) + wp.cross(e0, u2 - u0)
        dt = (de - t * wp.dot(t, de)) / le
        dn = (dc - n * wp.dot(n, dc)) / lc
        db = wp.cross(dn, t) + wp.cross(n, dt)
        return mat33(dt[0], db[0], dn[0], dt[1], db[1], dn[1], dt[2], db[2], dn[2])

    @wp.func
    def turn(rest: mat33, now: mat33):
        """``now rest^T``, identity where either frame is degenerate (zero)."""
        if wp.determinant(rest) < scalar(0.5) or wp.determinant(now) < scalar(0.5):
            return wp.identity(n=3, dtype=scalar)
        return now * wp.transpose(rest)

    @wp.kernel(enable_backward=False, module="unique")
    def bind_clamps(
        # Model: the strand's triangle (point indices), barycentric weights, authored ghost - root (m)
        triangle: wp.array(dtype=wp.vec3i),
        weights: wp.array(dtype=vec3),
        offset: wp.array(dtype=vec3),
        # Data in: the mesh's rest points (m), its points at the frame's start and end (m), their
        # velocities then (m/s; read only when frame_duration > 0), the frame's duration (s)
        rest_points: wp.array(dtype=vec3),
        points_start: wp.array(dtype=vec3),
        points_end: wp.array(dtype=vec3),
        velocities_start: wp.array(dtype=vec3),
        velocities_end: wp.array(dtype=vec3),
        frame_duration: scalar,
        # Data out: the ghosts at the frame's start and end (m), their path's deviations (m), the
        # clamps' rotations from the rest mesh at the frame's start and end
        ghost_start: wp.array(dtype=vec3),
        ghost_end: wp.array(dtype=vec3),
        deviation_start: wp.array(dtype=vec3),
        deviation_end: wp.array(dtype=vec3),
        rotation_start: wp.array(dtype=mat33),
        rotation_end: wp.array(dtype=mat33),
    ):
        s = wp.tid()
        i = triangle[s]
        w = weights[s]
        o = offset[s]
        rest = frame_of(rest_points[i[0]], rest_points[i[1]], rest_points[i[2]])
        a0 = points_start[i[0]]
        a1 = points_start[i[1]]
        a2 = points_start[i[2]]
        b0 = points_end[i[0]]
        b1 = points_end[i[1]]
        b2 = points_end[i[2]]
        ra = turn(rest, frame_of(a0, a1, a2))
        rb = turn(rest, frame_of(b0, b1, b2))
        rotation_start[s] = ra
        rotation_end[s] = rb
        ga = w[0] * a0 + w[1] * a1 + w[2] * a2 + ra * o
        gb = w[0] * b0 + w[1] * b1 + w[2] * b2 + rb * o
        ghost_start[s] = ga
        ghost_end[s] = gb
        if frame_duration > zero:
            chord = gb - ga
            back = wp.transpose(rest) * o
            ua0 = velocities_start[i[0]]
            ua1 = velocities_start[i[1]]
            ua2 = velocities_start[i[2]]
            ub0 = velocities_end[i[0]]
            ub1 = velocities_end[i[1]]
            ub2 = velocities_end[i[2]]
            va = w[0] * ua0 + w[1] * ua1 + w[2] * ua2
            vb = w[0] * ub0 + w[1] * ub1 + w[2] * ub2
            if wp.determinant(rest) > scalar(0.5):
                va = va + frame_rate(a0, a1, a2, ua0, ua1, ua2) * back
                vb = vb + frame_rate(b0, b1, b2, ub0, ub1, ub2) * back
            deviation_start[s] = frame_duration * va - chord
            deviation_end[s] = frame_duration * vb - chord
        else:
            deviation_start[s] = vec3()
            deviation_end[s] = vec3()

    return bind_clamps
