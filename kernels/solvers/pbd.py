"""Position Based Dynamics step: Gauss-Seidel distance constraints, one thread per strand.

One step of ``dt`` (s) (Mueller et al. 2007, equal unit masses, kinematic root):

1. the root is placed on its target on the frame's root path
   (:func:`~dftl_warp.kernels.core.root_path.root_on_path`); every other particle is predicted,
   ``p_i = x_i + dt v_i + dt^2 g``;
2. ``iterations`` Gauss-Seidel sweeps root -> tip project each segment to its rest length,
   moving both ends by equal shares (the root, of infinite mass, does not move);
3. ``v_i = (p_i - x_i)/dt``.

With a finite number of sweeps the constraints are not met: strands stretch, the more so the
longer the strand, the heavier the load and the fewer the sweeps. Velocities are kept as
``v + dt g`` plus every projection divided by ``dt`` (the same value as step 3), so the kernel
may run in place.
"""


import functools

import warp as wp

from ..core.layout import particle
from ..core.root_path import root_on_path


@functools.cache
def pbd_kernel(scalar):
    """The PBD step kernel for ``scalar`` precision (cached)."""
    vec3 = wp.types.vector(3, scalar)

    @wp.kernel(enable_backward=False, module="unique")
    def pbd_step(
        strand_base: wp.array(dtype=wp.int32),
        strand_stride: wp.array(dtype=wp.int32),
        strand_count: wp.array(dtype=wp.int32),
        root_start: wp.array(dtype=vec3),
        root_end: wp.array(dtype=vec3),
        root_deviation_start: wp.array(dtype=vec3),
        root_deviation_end: wp.array(dtype=vec3),
        root_alpha: scalar,
        rest_lengths: wp.array(dtype=scalar),
        gravity: vec3,
        dt: scalar,
        iterations: wp.int32,
        positions_in: wp.array(dtype=vec3),
        velocities_in: wp.array(dtype=vec3),
        positions_out: wp.array(dtype=vec3),
        velocities_out: wp.array(dtype=vec3),
    ):
        s = wp.tid()
        base = strand_base[s]
        stride = strand_stride[s]
        n = strand_count[s]
        inv_dt = scalar(1.0) / dt
        k0 = particle(base, stride, 0)
        root = root_on_path(root_start[s], root_end[s] - root_start[s], root_deviation_start[s],
                            root_deviation_end[s], root_alpha)
        velocities_out[k0] = (root - positions_in[k0]) * inv_dt
        positions_out[k0] = root
        for i in range(1, n):
            k = particle(base, stride, i)
            vi = velocities_in[k] + dt * gravity
            positions_out[k] = positions_in[k] + dt * vi
            velocities_out[k] = vi
        for it in range(iterations):
            for j in range(1, n):
                ka = particle(base, stride, j - 1)
                kb = particle(base, stride, j)
                d = positions_out[kb] - positions_out[ka]
                length = wp.length(d)
                if length > scalar(1.0e-30):
                    # share of the correction taken by the leader (0 for the kinematic root)
                    share = scalar(0.5)
                    if j == 1:
                        share = scalar(0.0)
                    corr = d * ((length - rest_lengths[kb]) / length)
                    positions_out[ka] = positions_out[ka] + share * corr
                    velocities_out[ka] = velocities_out[ka] + (share * inv_dt) * corr
                    positions_out[kb] = positions_out[kb] - (scalar(1.0) - share) * corr
                    velocities_out[kb] = velocities_out[kb] - ((scalar(1.0) - share) * inv_dt) * corr

    return pbd_step
