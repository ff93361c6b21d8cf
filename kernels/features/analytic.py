"""Analytic collider shapes: the signed distance of each, collider-local (m).

- sphere: ``size[0]`` radius, centred on the local origin;
- capsule: ``size[0]`` radius, ``size[1]`` half height of the core segment, along the unit
  local ``axis``;
- box: ``size`` half extents, centred;
- ellipsoid: ``size`` semi-axes along the local x, y, z, centred (a non-uniformly scaled USD
  Sphere). Its signed distance is exact (up to rounding): the closest point solves Eberly's
  one-dimensional root problem ("Distance from a point to an ellipse, an ellipsoid, or a
  hyperellipsoid", 2013), here by Newton's method from the left of the root, where the function
  is convex and decreasing so every iterate stays on the left and converges monotonically, in
  float64 whatever the step's precision.

Each ``*_sdf_func(scalar)`` returns ``sdf(q, size, axis) -> (d, n)``: the signed distance ``d``
of point ``q`` (negative inside) and the outward unit normal ``n`` of the closest surface point.
The response is shared (:func:`~dftl_warp.kernels.features.collide.analytic_collide_func`). Each
shape also answers where the segment from a particle's leader enters it (``*_entry_func``): round a
box's convex edges, or round a shape thinner than a segment (a capsule of 2 mm radius under 5 mm
segments, a small sphere, a flat ellipsoid's rim), the contact plane of the nearest point can lie
farther behind the leader than the rest length, and the particle then leaves by the tangent plane
where the segment enters.
"""


import functools

import warp as wp

from .collide import analytic_collider, tiny_length


@functools.cache
def sphere_sdf_func(scalar):
    vec3 = wp.types.vector(3, scalar)
    zero, one, tiny = scalar(0.0), scalar(1.0), tiny_length(scalar)

    @wp.func
    def sphere_sdf(q: vec3, size: vec3, axis: vec3):
        d = wp.length(q)
        n = vec3(zero, one, zero)
        if d > tiny:
            n = q / d
        return d - size[0], n

    return sphere_sdf


@functools.cache
def capsule_sdf_func(scalar):
    vec3 = wp.types.vector(3, scalar)
    zero, one, tiny = scalar(0.0), scalar(1.0), tiny_length(scalar)

    @wp.func
    def capsule_sdf(q: vec3, size: vec3, axis: vec3):
        a = wp.clamp(wp.dot(q, axis), -size[1], size[1])
        r = q - a * axis
        d = wp.length(r)
        n = vec3(zero, one, zero)
        if d > tiny:
            n = r / d
        return d - size[0], n

    return capsule_sdf


@functools.cache
def box_sdf_func(scalar):
    vec3 = wp.types.vector(3, scalar)
    zero = scalar(0.0)

    @wp.func
    def box_sdf(q: vec3, size: vec3, axis: vec3):
        e = vec3(wp.abs(q[0]) - size[0], wp.abs(q[1]) - size[1], wp.abs(q[2]) - size[2])
        s = vec3(wp.sign(q[0]), wp.sign(q[1]), wp.sign(q[2]))
        outside = vec3(wp.max(e[0], zero), wp.max(e[1], zero), wp.max(e[2], zero))
        lo = wp.length(outside)
        if lo > zero:
            return lo, wp.cw_mul(s, outside) / lo
        # inside: the nearest face
        if e[0] >= e[1] and e[0] >= e[2]:
            return e[0], vec3(s[0], zero, zero)
        if e[1] >= e[2]:
            return e[1], vec3(zero, s[1], zero)
        return e[2], vec3(zero, zero, s[2])

    return box_sdf


@functools.cache
def entry_func(scalar, ray_factory):
    """``entry(q, lead, size, axis) -> (found, n, d)``: where the segment from ``lead`` to ``q``
    enters the shape (``found`` false where ``lead`` is inside or the segment misses), the outward
    normal ``n`` there (a box's face, a smooth shape's tangent plane) and ``q``'s signed height
    ``d`` above that plane (negative behind it). ``ray(lead, direction, size, axis) -> (found, t,
    n)``: the first ``t >= 0`` where the ray ``lead + t direction`` (unit) enters the shape and the
    normal there (``found`` false where ``lead`` is inside or the ray misses)."""
    vec3 = wp.types.vector(3, scalar)
    zero, tiny = scalar(0.0), tiny_length(scalar)
    ray = ray_factory(scalar)

    @wp.func
    def entry(q: vec3, lead: vec3, size: vec3, axis: vec3):
        arm = q - lead
        length = wp.length(arm)
        n = vec3()
        if length <= tiny:
            return False, n, zero
        direction = arm / length
        found, t, n_e = ray(lead, direction, size, axis)
        if not found or t > length:
            return False, n, zero
        return True, n_e, (length - t) * wp.dot(direction, n_e)

    return entry


@functools.cache
def box_ray_func(scalar):
    """The ray's entry into the box: the face of its last slab entered (slab test)."""
    vec3 = wp.types.vector(3, scalar)
    zero, one, tiny, far = scalar(0.0), scalar(1.0), tiny_length(scalar), scalar(1.0e30)

    @wp.func
    def box_ray(lead: vec3, direction: vec3, size: vec3, axis: vec3):
        t_in = -far
        t_out = far
        face = int(-1)
        n = vec3()
        for i in range(3):
            if wp.abs(direction[i]) > tiny:
                a = (-size[i] - lead[i]) / direction[i]
                b = (size[i] - lead[i]) / direction[i]
                if wp.min(a, b) > t_in:
                    t_in = wp.min(a, b)
                    face = i
                t_out = wp.min(t_out, wp.max(a, b))
            elif wp.abs(lead[i]) > size[i]:
                t_out = -far  # parallel to this slab, outside it: the ray misses
        if face < 0 or t_in < zero or t_in > t_out:
            return False, t_in, n
        n[face] = -wp.sign(direction[face]) * one
        return True, t_in, n

    return box_ray


@functools.cache
def box_entry_func(scalar):
    return entry_func(scalar, box_ray_func)


@functools.cache
def interval_func(scalar):
    """``interval(a, b, c) -> (found, t0, t1)``: where ``a t^2 + 2 b t + c <= 0`` (``a >= 0``), the
    roots taken without cancellation; ``a`` near 0 (a ray along a cylinder's axis) gives all ``t``
    where ``c <= 0`` and none elsewhere."""
    zero, tiny, far = scalar(0.0), tiny_length(scalar), scalar(1.0e30)

    @wp.func
    def interval(a: scalar, b: scalar, c: scalar):
        if a <= tiny * tiny:
            return c <= zero, -far, far
        disc = b * b - a * c
        if disc < zero:
            return False, zero, zero
        root = wp.sqrt(disc)
        k = root - b
        if b >= zero:
            k = -(b + root)
        if k == zero:
            return True, zero, zero
        return True, wp.min(k / a, c / k), wp.max(k / a, c / k)

    return interval


@functools.cache
def smooth_ray_func(scalar, pieces_factory, surface_factory):
    """The ray's entry into a smooth shape: ``pieces(lead, direction, size, axis) -> (inside, t)``,
    whether ``lead`` is inside it, else the first ``t >= 0`` where the ray meets it (``far`` where
    it misses); ``surface(e, size, axis) -> (_, n)``: the outward unit normal ``n`` at the surface
    point ``e`` (the sphere's and capsule's signed distances serve)."""
    vec3 = wp.types.vector(3, scalar)
    far = scalar(1.0e30)
    pieces, surface = pieces_factory(scalar), surface_factory(scalar)

    @wp.func
    def smooth_ray(lead: vec3, direction: vec3, size: vec3, axis: vec3):
        inside, t = pieces(lead, direction, size, axis)
        if inside or t >= far:
            return False, t, vec3()
        _, n = surface(lead + t * direction, size, axis)
        return True, t, n

    return smooth_ray


@functools.cache
def _first(scalar):
    """``first(found, t0, t1, inside, t) -> (inside, t)``: a convex piece's interval ``[t0, t1]``
    along the ray merged into the union's ``inside`` and first entry ``t``."""
    zero = scalar(0.0)

    @wp.func
    def first(found: bool, t0: scalar, t1: scalar, inside: bool, t: scalar):
        if found and t1 >= zero:
            if t0 < zero:
                return True, t
            return inside, wp.min(t, t0)
        return inside, t

    return first


@functools.cache
def ellipsoid_pieces_func(scalar):
    """The ray's entry into the ellipsoid of semi-axes ``size`` (a sphere where they are equal):
    the unit sphere's, scaled (``t`` stays in the ray's own length)."""
    vec3 = wp.types.vector(3, scalar)
    one, far = scalar(1.0), scalar(1.0e30)
    interval, first = interval_func(scalar), _first(scalar)

    @wp.func
    def ellipsoid_pieces(lead: vec3, direction: vec3, size: vec3, axis: vec3):
        o = wp.cw_div(lead, size)
        v = wp.cw_div(direction, size)
        found, t0, t1 = interval(wp.dot(v, v), wp.dot(o, v), wp.dot(o, o) - one)
        return first(found, t0, t1, False, far)

    return ellipsoid_pieces


@functools.cache
def ellipsoid_surface_func(scalar):
    """``(0, n)``: the outward normal at the ellipsoid's surface point ``e``, its implicit gradient."""
    vec3 = wp.types.vector(3, scalar)

    @wp.func
    def ellipsoid_surface(e: vec3, size: vec3, axis: vec3):
        return scalar(0.0), wp.normalize(wp.cw_div(wp.cw_div(e, size), size))

    return ellipsoid_surface


@functools.cache
def sphere_pieces_func(scalar):
    vec3 = wp.types.vector(3, scalar)
    pieces = ellipsoid_pieces_func(scalar)

    @wp.func
    def sphere_pieces(lead: vec3, direction: vec3, size: vec3, axis: vec3):
        return pieces(lead, direction, vec3(size[0], size[0], size[0]), axis)

    return sphere_pieces


@functools.cache
def capsule_pieces_func(scalar):
    """The ray's entry into the capsule: the first of its two end balls and its cylinder between
    the end planes."""
    vec3 = wp.types.vector(3, scalar)
    one, tiny, far = scalar(1.0), tiny_length(scalar), scalar(1.0e30)
    interval, first = interval_func(scalar), _first(scalar)

    @wp.func
    def capsule_pieces(lead: vec3, direction: vec3, size: vec3, axis: vec3):
        r = size[0]
        h = size[1]
        inside = bool(False)
        t = far
        for end in range(2):
            o = lead - (scalar(2 * end - 1) * h) * axis
            found, t0, t1 = interval(one, wp.dot(o, direction), wp.dot(o, o) - r * r)
            inside, t = first(found, t0, t1, inside, t)
        s = wp.dot(lead, axis)
        v = wp.dot(direction, axis)
        o = lead - s * axis
        w = direction - v * axis
        found, t0, t1 = interval(wp.dot(w, w), wp.dot(o, w), wp.dot(o, o) - r * r)
        if wp.abs(v) > tiny:  # between the end planes
            lower = (-h - s) / v
            upper = (h - s) / v
            t0 = wp.max(t0, wp.min(lower, upper))
            t1 = wp.min(t1, wp.max(lower, upper))
        elif wp.abs(s) > h:
            found = False
        return first(found and t0 <= t1, t0, t1, inside, t)

    return capsule_pieces


@functools.cache
def sphere_ray_func(scalar):
    return smooth_ray_func(scalar, sphere_pieces_func, sphere_sdf_func)


@functools.cache
def capsule_ray_func(scalar):
    return smooth_ray_func(scalar, capsule_pieces_func, capsule_sdf_func)


@functools.cache
def ellipsoid_ray_func(scalar):
    return smooth_ray_func(scalar, ellipsoid_pieces_func, ellipsoid_surface_func)


@functools.cache
def sphere_entry_func(scalar):
    return entry_func(scalar, sphere_ray_func)


@functools.cache
def capsule_entry_func(scalar):
    return entry_func(scalar, capsule_ray_func)


@functools.cache
def ellipsoid_entry_func(scalar):
    return entry_func(scalar, ellipsoid_ray_func)


@functools.cache
def ellipsoid_sdf_func(scalar):
    vec3 = wp.types.vector(3, scalar)
    f64 = wp.float64
    zero64, one64 = f64(0.0), f64(1.0)

    @wp.func
    def ellipsoid_sdf(q: vec3, size: vec3, axis: vec3):
        e = wp.vec3d(f64(size[0]), f64(size[1]), f64(size[2]))
        em = wp.min(e[0], wp.min(e[1], e[2]))
        # first octant; a coordinate on a symmetry plane is moved off it by 1e-9 of the smallest
        # semi-axis (the distance moves by as much at most), which keeps the root off the pole
        floor = em * f64(1.0e-9)
        y = wp.vec3d(wp.max(wp.abs(f64(q[0])), floor), wp.max(wp.abs(f64(q[1])), floor),
                     wp.max(wp.abs(f64(q[2])), floor))
        z = wp.vec3d(y[0] / e[0], y[1] / e[1], y[2] / e[2])
        r = wp.vec3d((e[0] / em) * (e[0] / em), (e[1] / em) * (e[1] / em), (e[2] / em) * (e[2] / em))
        # G(s) = sum (r_i z_i / (s + r_i))^2 - 1 has one root on s > -1: G >= 0 left of it
        s = wp.max(r[0] * (z[0] - one64), wp.max(r[1] * (z[1] - one64), r[2] * (z[2] - one64)))
        for _ in range(48):
            g = -one64
            dg = zero64
            for i in range(3):
                a = r[i] * z[i] / (s + r[i])
                g = g + a * a
                dg = dg - f64(2.0) * a * a / (s + r[i])
            if g <= zero64 or dg >= zero64:
                break
            step = g / dg
            s = s - step
            if -step <= f64(1.0e-15) * (wp.abs(s) + one64):
                break
        x = wp.vec3d(r[0] * y[0] / (s + r[0]), r[1] * y[1] / (s + r[1]), r[2] * y[2] / (s + r[2]))
        d = wp.length(y - x)
        if z[0] * z[0] + z[1] * z[1] + z[2] * z[2] < one64:
            d = -d
        # the outward normal at the closest point: the gradient of the implicit surface there
        grad = wp.normalize(wp.vec3d(x[0] / (e[0] * e[0]), x[1] / (e[1] * e[1]), x[2] / (e[2] * e[2])))
        sx = one64
        sy = one64
        sz = one64
        if q[0] < scalar(0.0):
            sx = -one64
        if q[1] < scalar(0.0):
            sy = -one64
        if q[2] < scalar(0.0):
            sz = -one64
        n = vec3(scalar(sx * grad[0]), scalar(sy * grad[1]), scalar(sz * grad[2]))
        return scalar(d), n

    return ellipsoid_sdf


SPHERE = analytic_collider("spheres", "collide_sphere", sphere_sdf_func, sphere_entry_func)
CAPSULE = analytic_collider("capsules", "collide_capsule", capsule_sdf_func, capsule_entry_func)
BOX = analytic_collider("boxes", "collide_box", box_sdf_func, box_entry_func)
ELLIPSOID = analytic_collider("ellipsoids", "collide_ellipsoid", ellipsoid_sdf_func, ellipsoid_entry_func)
