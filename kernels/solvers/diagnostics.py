"""Per-strand diagnostics: energy per unit particle mass, stretch and speed.

Computed on demand (never inside the step), so a run that does not ask for them pays nothing.
"""


import functools

import warp as wp

from ..core.layout import particle


@functools.cache
def strand_diagnostics_kernel(scalar):
    """Kernel writing, per strand: energy (J/kg summed over free particles), max relative stretch
    and max speed (m/s) of its free particles. Accumulates in float64. A strand with a position or
    velocity that is not finite gets infinite stretch and speed (``wp.max`` drops a NaN: a blown-up
    strand read as unstretched and still)."""
    vec3 = wp.types.vector(3, scalar)

    @wp.kernel(enable_backward=False, module="unique")
    def strand_diagnostics(
        strand_base: wp.array(dtype=wp.int32),
        strand_stride: wp.array(dtype=wp.int32),
        strand_count: wp.array(dtype=wp.int32),
        rest_lengths: wp.array(dtype=scalar),
        gravity: vec3,
        positions: wp.array(dtype=vec3),
        velocities: wp.array(dtype=vec3),
        energy: wp.array(dtype=wp.float64),
        stretch: wp.array(dtype=wp.float64),
        speed: wp.array(dtype=wp.float64),
    ):
        s = wp.tid()
        base = strand_base[s]
        stride = strand_stride[s]
        n = strand_count[s]
        e = wp.float64(0.0)
        worst = wp.float64(0.0)
        fastest = wp.float64(0.0)
        k0 = particle(base, stride, 0)
        leader = positions[k0]
        blown = not (wp.isfinite(leader) and wp.isfinite(velocities[k0]))
        for i in range(1, n):
            k = particle(base, stride, i)
            x = positions[k]
            v = velocities[k]
            e += wp.float64(scalar(0.5) * wp.dot(v, v) - wp.dot(gravity, x))
            rest = rest_lengths[k]
            if rest > scalar(0.0):
                worst = wp.max(worst, wp.abs(wp.float64(wp.length(x - leader) / rest) - wp.float64(1.0)))
            fastest = wp.max(fastest, wp.float64(wp.length(v)))
            if not (wp.isfinite(x) and wp.isfinite(v)):
                blown = True
            leader = x
        if blown:
            worst = wp.float64(wp.inf)
            fastest = wp.float64(wp.inf)
        energy[s] = e
        stretch[s] = worst
        speed[s] = fastest

    return strand_diagnostics
