"""Clean starts: particles that start inside a collider are measured and moved out.

Both kernels reuse the registered colliders' collide functions
(:func:`~dftl_warp.kernels.features.collide.collide_all_func`) without the continuous test and
with the previous position equal to the current one (no friction), so every shape, present and
future, is covered:

- :func:`penetration_kernel`: per particle, collide with ``leader = x`` and ``rest = 0``: the
  response is then the projection alone, along the shortest path, so the distance moved is the
  penetration of the contact distance (``radius - d``; over ``radius`` the particle is inside the
  surface);
- :func:`resolve_kernel`: per strand, from the root, each particle is projected to its rest length
  behind its leader (follow the leader), then collided and projected again, ``iterations`` rounds:
  the sweep of the step without its dynamics.
"""


import functools

import warp as wp

from ..core.layout import particle
from .collide import collide_all_func, tiny_length


@functools.cache
def follow_func(scalar):
    """``follow(leader, x, rest, fallback)``: ``x`` put ``rest`` from ``leader`` toward itself (along
    ``fallback`` when it sits on the leader)."""
    vec3 = wp.types.vector(3, scalar)
    tiny = tiny_length(scalar)

    @wp.func
    def follow_clean(leader: vec3, x: vec3, rest: scalar, fallback: vec3):
        d = x - leader
        length = wp.length(d)
        if length > tiny:
            return leader + d * (rest / length)
        return leader + rest * fallback

    return follow_clean


@functools.cache
def penetration_kernel(scalar, Features, flags: frozenset):
    vec3 = wp.types.vector(3, scalar)
    collide_all = collide_all_func(scalar, Features, flags)

    @wp.kernel(enable_backward=False, module="unique")
    def penetration(strand_base: wp.array(dtype=wp.int32), strand_stride: wp.array(dtype=wp.int32),
                    strand_count: wp.array(dtype=wp.int32), features: Features,
                    positions: wp.array(dtype=vec3), depth: wp.array2d(dtype=scalar),
                    radius: wp.array2d(dtype=scalar)):
        s, i = wp.tid()
        depth[s, i] = scalar(0.0)
        radius[s, i] = scalar(0.0)
        if i < strand_count[s]:
            k = particle(strand_base[s], strand_stride[s], i)
            x = positions[k]
            r = features.particle_radius[k]
            radius[s, i] = r
            y, touched = collide_all(features, x, x, x, scalar(0.0), False, r)
            if touched:
                depth[s, i] = wp.length(y - x)

    return penetration


@functools.cache
def resolve_kernel(scalar, Features, flags: frozenset):
    vec3 = wp.types.vector(3, scalar)
    collide_all = collide_all_func(scalar, Features, flags)
    follow = follow_func(scalar)
    tiny = tiny_length(scalar)

    @wp.kernel(enable_backward=False, module="unique")
    def resolve(strand_base: wp.array(dtype=wp.int32), strand_stride: wp.array(dtype=wp.int32),
                strand_count: wp.array(dtype=wp.int32), rest_lengths: wp.array(dtype=scalar),
                features: Features, iterations: int, positions: wp.array(dtype=vec3)):
        s = wp.tid()
        base = strand_base[s]
        stride = strand_stride[s]
        leader = positions[particle(base, stride, 0)]
        leader_old = leader
        fallback = vec3(scalar(1.0), scalar(0.0), scalar(0.0))
        moved = bool(False)
        for i in range(1, strand_count[s]):
            k = particle(base, stride, i)
            x_old = positions[k]
            rest = rest_lengths[k]
            radius = features.particle_radius[k]
            if not moved:
                # up to the first particle in contact the strand stays exactly as it is: re-placing
                # it at its rest lengths would move it by round-off, so a strand's start would depend
                # on whether other strands of its launch needed a sweep (a groom split over devices
                # started otherwise than on one)
                y, touched = collide_all(features, x_old, x_old, leader, rest, False, radius)
                if not touched:
                    leader_old = x_old
                    leader = x_old
                    continue
                moved = True
            if wp.length(x_old - leader_old) > tiny:
                fallback = wp.normalize(x_old - leader_old)
            x = follow(leader, x_old, rest, fallback)
            for it in range(iterations):
                x, touched = collide_all(features, x, x, leader, rest, False, radius)
                if not touched:
                    break
                x = follow(leader, x, rest, fallback)
            positions[k] = x
            leader_old = x_old
            leader = x

    return resolve


@functools.cache
def scale_velocities_kernel(scalar):
    vec3 = wp.types.vector(3, scalar)

    @wp.kernel(enable_backward=False, module="unique")
    def scale_velocities(strand_base: wp.array(dtype=wp.int32), strand_stride: wp.array(dtype=wp.int32),
                         strand_count: wp.array(dtype=wp.int32), factor: scalar, velocities: wp.array(dtype=vec3)):
        s = wp.tid()
        for i in range(strand_count[s]):
            k = particle(strand_base[s], strand_stride[s], i)
            velocities[k] = velocities[k] * factor

    return scale_velocities


@functools.cache
def motion_kernel(scalar):
    """Largest distance between ``positions`` and ``previous`` over every particle (atomic max
    into ``largest[0]``, float32), then ``previous`` set to ``positions``."""
    vec3 = wp.types.vector(3, scalar)

    @wp.kernel(enable_backward=False, module="unique")
    def motion(strand_base: wp.array(dtype=wp.int32), strand_stride: wp.array(dtype=wp.int32),
               strand_count: wp.array(dtype=wp.int32), positions: wp.array(dtype=vec3),
               previous: wp.array(dtype=vec3), largest: wp.array(dtype=wp.float32)):
        s = wp.tid()
        m = wp.float32(0.0)
        for i in range(strand_count[s]):
            k = particle(strand_base[s], strand_stride[s], i)
            m = wp.max(m, wp.float32(wp.length(positions[k] - previous[k])))
            previous[k] = positions[k]
        wp.atomic_max(largest, 0, m)

    return motion
