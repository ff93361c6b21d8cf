"""Synthetic grooms made on the device, for benchmarks too large to build on the host."""

import functools

import warp as wp

from .layout import particle


@functools.cache
def straight_strands_kernel(scalar):
    """Kernel placing strand ``s`` along +x from ``(0, 0, spacing * s)``, with rest lengths."""
    vec3 = wp.types.vector(3, scalar)

    @wp.kernel(enable_backward=False, module="unique")
    def straight_strands(
        strand_base: wp.array(dtype=wp.int32),
        strand_stride: wp.array(dtype=wp.int32),
        strand_count: wp.array(dtype=wp.int32),
        spacing: scalar,
        positions: wp.array(dtype=vec3),
        rest_lengths: wp.array(dtype=scalar),
        root_rest: wp.array(dtype=vec3),
    ):
        s = wp.tid()
        z = spacing * scalar(s % 1024)
        for i in range(strand_count[s]):
            k = particle(strand_base[s], strand_stride[s], i)
            positions[k] = vec3(spacing * scalar(i), scalar(0.0), z)
            if i == 0:
                rest_lengths[k] = scalar(0.0)
                root_rest[s] = positions[k]
            else:
                rest_lengths[k] = spacing

    return straight_strands


@functools.cache
def copy_kernel():
    """Element-wise vec4 copy: the bandwidth ceiling's second measure (beside ``wp.copy``)."""

    @wp.kernel(enable_backward=False, module="unique")
    def copy_elements(src: wp.array(dtype=wp.vec4), dst: wp.array(dtype=wp.vec4)):
        i = wp.tid()
        dst[i] = src[i]

    return copy_elements
