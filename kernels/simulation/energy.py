"""Per-strand energy above the hanging rest state, for the energy-growth monitor.

Per unit particle mass (J/kg), summed over a strand's free particles (float64)::

    E_avail = sum_i  |v_i|^2 / 2  -  g . (x_i - x_0)  +  |g| L_i

where ``x_0`` is the root and ``L_i`` the rest length along the strand from the root to particle
``i``. It is zero for a strand hanging straight down at rest and positive otherwise (for
an inextensible strand), whatever the world origin: the quantity is measured from the root.
"""


import functools

import warp as wp

from ..core.layout import particle


@functools.cache
def available_energy_kernel(scalar):
    """Kernel writing per strand: available energy (J/kg), root speed (m/s), root position (m,
    device coordinates), 1 if any position or velocity is not finite (else 0)."""
    vec3 = wp.types.vector(3, scalar)

    @wp.kernel(enable_backward=False, module="unique")
    def available_energy(
        strand_base: wp.array(dtype=wp.int32),
        strand_stride: wp.array(dtype=wp.int32),
        strand_count: wp.array(dtype=wp.int32),
        rest_lengths: wp.array(dtype=scalar),
        gravity: wp.vec3d,
        positions: wp.array(dtype=vec3),
        velocities: wp.array(dtype=vec3),
        energy: wp.array(dtype=wp.float64),
        root_speed: wp.array(dtype=wp.float64),
        root_position: wp.array(dtype=wp.vec3d),
        not_finite: wp.array(dtype=wp.int32),
    ):
        s = wp.tid()
        base = strand_base[s]
        stride = strand_stride[s]
        n = strand_count[s]
        g = wp.length(gravity)
        k0 = particle(base, stride, 0)
        x0 = positions[k0]
        v0 = velocities[k0]
        bad = wp.int32(0)
        if not (wp.isfinite(x0) and wp.isfinite(v0)):
            bad = 1
        e = wp.float64(0.0)
        along = wp.float64(0.0)
        for i in range(1, n):
            k = particle(base, stride, i)
            x = positions[k]
            v = velocities[k]
            if not (wp.isfinite(x) and wp.isfinite(v)):
                bad = 1
            dx = x - x0
            along += wp.float64(rest_lengths[k])
            rel = wp.vec3d(wp.float64(dx[0]), wp.float64(dx[1]), wp.float64(dx[2]))
            vd = wp.vec3d(wp.float64(v[0]), wp.float64(v[1]), wp.float64(v[2]))
            e += wp.float64(0.5) * wp.dot(vd, vd) - wp.dot(gravity, rel) + g * along
        energy[s] = e
        root_speed[s] = wp.float64(wp.length(v0))
        root_position[s] = wp.vec3d(wp.float64(x0[0]), wp.float64(x0[1]), wp.float64(x0[2]))
        not_finite[s] = bad

    return available_energy
