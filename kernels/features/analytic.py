"""Analytic collider shapes: the signed distance of each, collider-local (m).

- sphere: ``size[0]`` radius, centred on the local origin;
- capsule: ``size[0]`` radius, ``size[1]`` half height of the core segment, along the unit
  local ``axis``;
- box: ``size`` half extents, centred.

Each ``*_sdf_func(scalar)`` returns ``sdf(q, size, axis) -> (d, n)``: the signed distance ``d``
of point ``q`` (negative inside) and the outward unit normal ``n`` of the closest surface point.
The response is shared (:func:`~dftl_warp.kernels.features.collide.analytic_collide_func`).
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


SPHERE = analytic_collider("spheres", "collide_sphere", sphere_sdf_func)
CAPSULE = analytic_collider("capsules", "collide_capsule", capsule_sdf_func)
BOX = analytic_collider("boxes", "collide_box", box_sdf_func)
