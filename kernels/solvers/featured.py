"""The DFTL step specialized to a scene's feature set.

:func:`featured_step_kernel` builds, per precision, correction form and feature set, one kernel
whose code holds exactly the features asked for: each feature's code sits under
``if wp.static(FLAG):`` and is dropped at code generation when the flag is off, and its
parameters travel in a Warp struct (:func:`~dftl_warp.kernels.features.step.feature_struct`)
that has fields for the present
features only. The empty feature set is never built here: :func:`dftl_warp.kernels.solvers.ftl.step_kernel`
returns the bare kernel for it.

Flags (:data:`FLAGS`) and where they act in the sweep of particle ``i`` (root excluded):

- ``hair_hair``: velocity pulled toward the grid velocity, pushed down the density gradient
  (``kernels/grid.py``), from the particle's previous position;
- ``drag`` (1/s, per strand) toward the air velocity: ``v = w + (v - w) exp(-drag dt)``, with
  ``w`` zero, or the frame's ``wind`` velocity (interpolated across the frame), plus
  ``wind_noise`` (curl noise in space and time, sampled every :data:`NOISE_STRIDE` particles
  along a strand and held in between: the noise is the costliest term of the step);
- prediction ``p = x + dt v + dt^2 g`` (and the prior form's carried correction);
- follow-the-leader projection to the rest length;
- colliders (the registered shapes: ``spheres``, ``capsules``, ``boxes``, ``meshes``, in
  :data:`~dftl_warp.kernels.features.collide.COLLIDER_KERNELS`): ``iterations`` rounds of
  collide-then-project-to-rest-length (``kernels/features/collide.py``), the first with a
  continuous test; the present shapes are composed at code generation
  (:func:`~dftl_warp.kernels.features.collide.collide_all_func`). The rest length is restored
  last, so collisions never stretch a segment.
"""

import warp as wp

from ..core.arith import madd
from ..core.factory import kernel_factory
from ..core.layout import particle
from ..core.root_path import root_on_path
from ..features.collide import collide_all_func, collider_flags
from ..features.grid import grid_sample_func
from ..features.step import NOISE_STRIDE, check_flags, feature_struct  # noqa: F401  (re-exported)
from .ftl import STEP_MODULE_OPTIONS, carried_func, follow_func

#: CUDA register cap of the featured sweep (None: the compiler's choice; ``scripts/profile_features.py
#: --sweep-caps`` measures others)
CUDA_MAX_REGISTERS = None


@kernel_factory
def featured_step_kernel(scalar, correction: str, flags: frozenset, scale_pushes: bool = True):
    """The DFTL step for ``scalar`` precision, ``correction`` form and the non-empty ``flags``;
    ``scale_pushes``: :func:`~.ftl.carried_func`."""
    flags = check_flags(flags)
    if not flags:
        raise ValueError("the empty feature set runs the bare step (kernels.ftl.step_kernel)")
    vec3 = wp.types.vector(3, scalar)
    Features = feature_struct(scalar, flags)
    follow = follow_func(scalar)
    carried = carried_func(scalar, scale_pushes)
    grid_sample = grid_sample_func(scalar)

    PRIOR = correction == "prior"
    COLLIDE = bool(flags & set(collider_flags()))
    collide_all = collide_all_func(scalar, Features, flags) if COLLIDE else None
    DRAG = "drag" in flags
    WIND = "wind" in flags
    WIND_NOISE = "wind_noise" in flags
    HAIR_HAIR = "hair_hair" in flags
    one = scalar(1.0)

    @wp.kernel(enable_backward=False, module="unique", module_options=STEP_MODULE_OPTIONS,
               cuda_max_registers=CUDA_MAX_REGISTERS)
    def dftl_step_featured(
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
        damping: scalar,
        features: Features,
        positions_in: wp.array(dtype=vec3),
        velocities_in: wp.array(dtype=vec3),
        corrections_in: wp.array(dtype=vec3),
        positions_out: wp.array(dtype=vec3),
        velocities_out: wp.array(dtype=vec3),
        corrections_out: wp.array(dtype=vec3),
    ):
        s = wp.tid()
        base = strand_base[s]
        stride = strand_stride[s]
        n = strand_count[s]
        inv_dt = one / dt
        gdt2 = gravity * (dt * dt)
        k = particle(base, stride, 0)
        root = root_on_path(root_start[s], root_end[s] - root_start[s], root_deviation_start[s],
                            root_deviation_end[s], root_alpha)
        leader_old = positions_in[k]
        positions_out[k] = root
        velocities_out[k] = (root - leader_old) * inv_dt
        if wp.static(PRIOR):
            corrections_out[k] = vec3()
        leader = root
        k_prev = k

        if wp.static(DRAG):
            decay = wp.exp(-features.drag[s] * dt)
            air = vec3()
            if wp.static(WIND):
                w0 = features.wind_velocity[0]
                air = w0 + root_alpha * (features.wind_velocity[1] - w0)
            if wp.static(WIND_NOISE):
                t0 = features.wind_time[0]
                time = t0 + root_alpha * (features.wind_time[1] - t0)
                noise_state = wp.uint32(features.noise_seed)
                gust = vec3()
        if wp.static(HAIR_HAIR):
            blend_grid = one - wp.exp(-features.grid_friction * dt)
            push = features.grid_repulsion * features.grid_h * dt

        for i in range(1, n):
            k = particle(base, stride, i)
            x_old = positions_in[k]
            v = velocities_in[k]
            if wp.static(HAIR_HAIR):
                v_grid, grad = grid_sample(x_old, features.grid_weights[k], features.grid_threshold,
                                           features.grid_lower, features.grid_inv_h, features.grid_nx,
                                           features.grid_ny, features.grid_nz, features.grid_density,
                                           features.grid_mass, features.grid_momentum)
                v = v + blend_grid * (v_grid - v) - push * grad
            if wp.static(DRAG):
                w = air
                if wp.static(WIND_NOISE):
                    if (i - 1) % NOISE_STRIDE == 0:
                        xyzt = wp.vec4f(wp.float32(x_old[0] * features.noise_inv_scale),
                                        wp.float32(x_old[1] * features.noise_inv_scale),
                                        wp.float32(x_old[2] * features.noise_inv_scale),
                                        wp.float32(time * features.noise_frequency))
                        gust = features.noise_amplitude * vec3(wp.curlnoise(noise_state, xyzt))
                    w = w + gust
                v = w + (v - w) * decay
            p = madd(dt, v, x_old) + gdt2
            if wp.static(PRIOR):
                if i + 1 < n:
                    p = madd(-damping, corrections_in[particle(base, stride, i + 1)], p)
            rest = rest_lengths[k]
            x = follow(leader, p, rest, leader_old, x_old)
            correction = carried(x, p, leader, x_old, rest)
            if wp.static(COLLIDE):
                radius = features.particle_radius[k]
                for it in range(features.collider_iterations):
                    x, touched = collide_all(features, x, x_old, leader, rest, it == 0, radius)
                    if not touched:
                        break
                    x = follow(leader, x, rest, leader_old, x_old)
            positions_out[k] = x
            if wp.static(PRIOR):
                velocities_out[k] = (x - x_old) * inv_dt
                corrections_out[k] = correction
            else:
                if i > 1:
                    velocities_out[k_prev] = madd(-(damping * inv_dt), correction, (leader - leader_old) * inv_dt)
            leader = x
            leader_old = x_old
            k_prev = k
        if wp.static(not PRIOR):
            if n > 1:
                velocities_out[k_prev] = (leader - leader_old) * inv_dt

    return dftl_step_featured
