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
The response is shared (:func:`~dftl_warp.kernels.features.collide.analytic_collide_func`). The box
also answers which face the segment from a particle's leader enters it through
(:func:`box_entry_func`): round its convex edges, a contact plane can lie farther behind the leader
than the rest length, and the particle then leaves by that face.
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
def box_entry_func(scalar):
    """``entry(q, lead, size) -> (found, n, d)``: the face the segment from ``lead`` to ``q`` enters
    the box through (slab test; ``found`` false where ``lead`` is inside or the segment misses),
    its outward normal ``n`` and ``q``'s signed height ``d`` above its plane (negative behind it)."""
    vec3 = wp.types.vector(3, scalar)
    zero, one, tiny = scalar(0.0), scalar(1.0), tiny_length(scalar)

    @wp.func
    def box_entry(q: vec3, lead: vec3, size: vec3):
        arm = q - lead
        length = wp.length(arm)
        n = vec3()
        if length <= tiny:
            return False, n, zero
        direction = arm / length
        t_in = -length
        t_out = length
        face = int(-1)
        for i in range(3):
            if wp.abs(direction[i]) > tiny:
                a = (-size[i] - lead[i]) / direction[i]
                b = (size[i] - lead[i]) / direction[i]
                if wp.min(a, b) > t_in:
                    t_in = wp.min(a, b)
                    face = i
                t_out = wp.min(t_out, wp.max(a, b))
            elif wp.abs(lead[i]) > size[i]:
                t_out = -length  # parallel to this slab, outside it: the segment misses
        if face < 0 or t_in < zero or t_in > t_out:
            return False, n, zero
        n[face] = -wp.sign(direction[face]) * one
        return True, n, (length - t_in) * direction[face] * n[face]

    return box_entry


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


SPHERE = analytic_collider("spheres", "collide_sphere", sphere_sdf_func)
CAPSULE = analytic_collider("capsules", "collide_capsule", capsule_sdf_func)
BOX = analytic_collider("boxes", "collide_box", box_sdf_func, box_entry_func)
ELLIPSOID = analytic_collider("ellipsoids", "collide_ellipsoid", ellipsoid_sdf_func)
