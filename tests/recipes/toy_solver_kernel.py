# kernels/solvers/toy.py
"""The toy solver's step (the solver recipe of docs/architecture.md), one thread per strand."""

import functools

import warp as wp

from ..core.layout import particle


@functools.cache
def toy_kernel(scalar):
    vec3 = wp.types.vector(3, scalar)

    @wp.kernel(enable_backward=False, module="unique")
    def toy_step(
        strand_base: wp.array(dtype=wp.int32),
        strand_stride: wp.array(dtype=wp.int32),
        strand_count: wp.array(dtype=wp.int32),
        root_start: wp.array(dtype=vec3),
        root_end: wp.array(dtype=vec3),
        root_alpha: scalar,
        rest_lengths: wp.array(dtype=scalar),
        gravity: vec3,
        dt: scalar,
        positions_in: wp.array(dtype=vec3),
        velocities_in: wp.array(dtype=vec3),
        positions_out: wp.array(dtype=vec3),
        velocities_out: wp.array(dtype=vec3),
    ):
        s = wp.tid()
        base = strand_base[s]
        stride = strand_stride[s]
        inv_dt = scalar(1.0) / dt
        k0 = particle(base, stride, 0)
        leader = root_start[s] + root_alpha * (root_end[s] - root_start[s])
        velocities_out[k0] = (leader - positions_in[k0]) * inv_dt
        positions_out[k0] = leader
        for i in range(1, strand_count[s]):
            k = particle(base, stride, i)
            x = positions_in[k]
            p = x + dt * (velocities_in[k] + dt * gravity)
            d = p - leader
            length = wp.length(d)
            if length > scalar(1.0e-30):
                p = leader + d * (rest_lengths[k] / length)
            velocities_out[k] = (p - x) * inv_dt
            positions_out[k] = p
            leader = p

    return toy_step
