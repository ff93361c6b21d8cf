"""The velocity features of a step in their own pass before the sweep: hair-hair, drag, wind and
its curl noise.

These features read only the step's input State (positions and velocities, m and m/s) and the
hair-hair grid, never what the sweep computes, so nothing ties them to the sweep's chain of one
particle after another. Inside the sweep they lengthen that chain (each particle's grid read and
noise wait for the particle before), and their registers take occupancy from it. Here they run
:data:`~dftl_warp.kernels.features.step.NOISE_STRIDE` particles per thread, so a strand of 32
particles has four threads where the sweep has one, and the sweep that follows carries only the
colliders (or is the bare step). The arithmetic is the sweep's own, in the same order.

Two forms, one per solver:

- ``"velocity"`` (DFTL): each free particle's velocity after hair-hair, then drag toward the air
  (m/s), exactly as the featured sweep (``kernels/solvers/featured.py``) applied them; the sweep
  then predicts from it.
- ``"acceleration"`` (the elastic step, ``kernels/solvers/elastic.py``, which takes drag and the
  grid's friction implicitly): per free particle ``(a, c)``, the acceleration toward the air and
  the grid, ``a = c_air w + c_grid v_grid - repulsion h grad(rho)`` (m/s^2), and the rate
  ``c = c_air + c_grid`` (1/s) of the implicit drag; ``c_air`` is the solver's own drag plus the
  Drag feature's.

The curl noise is sampled at the first particle of each block of ``NOISE_STRIDE`` and held over
the block, as the sweeps hold it. Roots are left alone (no sweep reads their input velocity).
"""


import functools

import warp as wp

from ..core.layout import particle
from .grid import grid_sample_func
from .step import NOISE_STRIDE, check_flags, feature_struct

#: the feature flags this pass applies (the others, the colliders', stay in the sweep)
VELOCITY_FLAGS = frozenset({"drag", "wind", "wind_noise", "hair_hair"})

#: CUDA register cap of the pass (None: the compiler's choice, 107 registers on sm_90;
#: ``scripts/profile_features.py --aux-caps`` measures others)
CUDA_MAX_REGISTERS = None

#: the two output forms (see the module docstring)
FORMS = ("velocity", "acceleration")


def split_flags(flags) -> tuple:
    """``(velocity_flags, sweep_flags)``: the part of ``flags`` this pass applies, and the rest."""
    flags = check_flags(flags)
    return flags & VELOCITY_FLAGS, flags - VELOCITY_FLAGS


def blocks_per_strand(longest: int) -> int:
    """Threads per strand of the pass (the launch's first dimension) for strands of up to ``longest``
    vertices: one per ``NOISE_STRIDE`` free particles."""
    return max(0, (int(longest) - 1 + NOISE_STRIDE - 1) // NOISE_STRIDE)


@functools.cache
def velocity_features_kernel(scalar, real, flags: frozenset, form: str):
    """The pass for States stored in ``scalar``, computing in ``real`` (the DFTL form: ``real`` is
    ``scalar``), applying ``flags`` (a non-empty subset of :data:`VELOCITY_FLAGS`) in ``form``.

    Launch with ``dim=(blocks_per_strand(longest), num_strands)``; the second index is the strand,
    so a warp's threads take one block of 32 neighbouring strands (the layout's coalesced rows)."""
    flags = check_flags(flags)
    if not flags or flags - VELOCITY_FLAGS:
        raise ValueError(f"the velocity pass applies a non-empty subset of {sorted(VELOCITY_FLAGS)}, "
                         f"got {sorted(flags)}")
    if form not in FORMS:
        raise ValueError(f"unknown form {form!r}; choose {' or '.join(FORMS)}")
    if form == "velocity" and real != scalar:
        raise ValueError("the velocity form computes in the States' precision")
    Features = feature_struct(scalar, flags)
    vec3s = wp.types.vector(3, scalar)
    vec3 = wp.types.vector(3, real)
    vec4 = wp.types.vector(4, real)
    grid_sample = grid_sample_func(scalar)
    VELOCITY = form == "velocity"
    DRAG = "drag" in flags
    WIND = "wind" in flags
    WIND_NOISE = "wind_noise" in flags
    HAIR_HAIR = "hair_hair" in flags
    one = real(1.0)

    @wp.func
    def ld(v: vec3s):
        return vec3(real(v[0]), real(v[1]), real(v[2]))

    @wp.kernel(enable_backward=False, module="unique", module_options={"fuse_fp": False},
               cuda_max_registers=CUDA_MAX_REGISTERS)
    def velocity_features(
        # Model:
        strand_base: wp.array(dtype=wp.int32),
        strand_stride: wp.array(dtype=wp.int32),
        strand_count: wp.array(dtype=wp.int32),
        # Step:
        root_alpha: real,         # where in the frame this step ends, [0, 1]
        dt: real,                 # s
        drag: real,               # the solver's own drag, 1/s (acceleration form only)
        features: Features,
        # State in:
        positions_in: wp.array(dtype=vec3s),
        velocities_in: wp.array(dtype=vec3s),
        # Data out (per particle; roots untouched): velocities (m/s) or (a, c) (m/s^2, 1/s)
        velocities_out: wp.array(dtype=vec3s),
        accelerations_out: wp.array(dtype=vec4),
    ):
        b, s = wp.tid()
        n = strand_count[s]
        first = 1 + b * NOISE_STRIDE
        if first >= n:
            return
        last = wp.min(n, first + NOISE_STRIDE)
        base = strand_base[s]
        stride = strand_stride[s]
        rate = drag
        air = vec3()
        if wp.static(DRAG):
            rate = drag + real(features.drag[s])
            if wp.static(VELOCITY):
                decay = wp.exp(-real(features.drag[s]) * dt)
            if wp.static(WIND):
                w0 = ld(features.wind_velocity[0])
                air = w0 + root_alpha * (ld(features.wind_velocity[1]) - w0)
            if wp.static(WIND_NOISE):
                t0 = features.wind_time[0]
                time = t0 + scalar(root_alpha) * (features.wind_time[1] - t0)
                x_first = positions_in[particle(base, stride, first)]
                xyzt = wp.vec4f(wp.float32(x_first[0] * features.noise_inv_scale),
                                wp.float32(x_first[1] * features.noise_inv_scale),
                                wp.float32(x_first[2] * features.noise_inv_scale),
                                wp.float32(time * features.noise_frequency))
                air = air + real(features.noise_amplitude) * vec3(wp.curlnoise(wp.uint32(features.noise_seed), xyzt))
        if wp.static(HAIR_HAIR):
            friction = real(features.grid_friction)
            blend_grid = one - wp.exp(-friction * dt)
            push = real(features.grid_repulsion * features.grid_h)
        for i in range(first, last):
            k = particle(base, stride, i)
            if wp.static(VELOCITY):
                v = ld(velocities_in[k])
                if wp.static(HAIR_HAIR):
                    v_grid, grad = grid_sample(positions_in[k], features.grid_weights[k], features.grid_threshold,
                                               features.grid_lower,
                                               features.grid_inv_h, features.grid_nx, features.grid_ny,
                                               features.grid_nz, features.grid_density, features.grid_mass,
                                               features.grid_momentum)
                    v = v + blend_grid * (ld(v_grid) - v) - (push * dt) * ld(grad)
                if wp.static(DRAG):
                    v = air + (v - air) * decay
                velocities_out[k] = vec3s(scalar(v[0]), scalar(v[1]), scalar(v[2]))
            else:
                a = vec3()
                c = rate
                if wp.static(DRAG):
                    a = rate * air
                if wp.static(HAIR_HAIR):
                    v_grid, grad = grid_sample(positions_in[k], features.grid_weights[k], features.grid_threshold,
                                               features.grid_lower,
                                               features.grid_inv_h, features.grid_nx, features.grid_ny,
                                               features.grid_nz, features.grid_density, features.grid_mass,
                                               features.grid_momentum)
                    a = a + friction * ld(v_grid) - push * ld(grad)
                    c = c + friction
                accelerations_out[k] = vec4(a[0], a[1], a[2], c)

    return velocity_features
