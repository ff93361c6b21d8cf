# kernels/features/cylinder.py
"""The toy cylinder collider's signed distance (the collider recipe of docs/architecture.md):
``size[0]`` radius, ``size[1]`` half height, along the unit local ``axis``, centred."""

import functools

import warp as wp

from .collide import analytic_collider, tiny_length


@functools.cache
def cylinder_sdf_func(scalar):
    vec3 = wp.types.vector(3, scalar)
    zero, one, tiny = scalar(0.0), scalar(1.0), tiny_length(scalar)

    @wp.func
    def cylinder_sdf(q: vec3, size: vec3, axis: vec3):
        a = wp.dot(q, axis)
        r = q - a * axis
        rl = wp.length(r)
        radial = vec3(one, zero, zero)
        if rl > tiny:
            radial = r / rl
        cap = axis
        if a < zero:
            cap = -axis
        dr = rl - size[0]
        da = wp.abs(a) - size[1]
        if dr > zero and da > zero:
            out = wp.sqrt(dr * dr + da * da)
            return out, (dr * radial + da * cap) / out
        if dr > da:
            return dr, radial
        return da, cap

    return cylinder_sdf


CYLINDER = analytic_collider("cylinders", "collide_cylinder", cylinder_sdf_func)
