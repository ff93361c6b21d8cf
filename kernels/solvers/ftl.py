"""Follow-the-leader step kernels: one thread per strand, a sequential sweep root -> tip.

Each kernel advances every strand by one substep ``dt`` (s):

1. the root (particle 0) is placed on its kinematic target, ``root_alpha`` of the way along the
   frame's root path (:func:`~dftl_warp.kernels.core.root_path.root_on_path`: from the start to the
   end target, linear unless the Control gave the roots velocities);
2. every other particle is predicted, ``p_i = x_i + dt v_i + dt^2 g`` (``g`` in m/s^2, or stage
   units/s^2), then pulled behind its leader,
   ``x_i = x_{i-1} + l_i (p_i - x_{i-1}) / |p_i - x_{i-1}|``;
3. velocities are corrected with ``damping`` ``s`` in one of two forms:

   - *posterior* (Mueller et al. 2012, eq. 1-3): ``v_i = (x_i - x_i_old)/dt - s dx_{i+1}/dt``,
     ``dx_{i+1} = x_{i+1} - p_{i+1}`` (zero at the tip);
   - *prior* (the seed's eq. 4-6): the previous step's correction of particle ``i+1`` enters the
     prediction, ``p_i -= s dx_{i+1}^{n-1}``, and ``v_i = (x_i - x_i_old)/dt``.

   The correction a follower hands its leader (:func:`carried_func`) is ``x - p`` where the link
   pulls; where it *pushes* (``x - p`` points away from the leader) it is scaled by
   ``max(1 - a m, 0)``, ``m`` the follower's motion in the step over its rest length and ``a``
   :data:`PUSH_MOTION_SCALE`. Unscaled, the lagged push of a follower that moves most of a segment
   every step pumps energy into folded, fast strands (docs/accuracy/folded.md); ``m`` is
   ``|v| dt / l``, so the scaling vanishes as ``dt -> 0`` and the convergence to the constrained
   dynamics is kept (a change of order ``dt`` in a push of order ``dt^2``: below DFTL's own
   first-order error).

Both forms produce the same positions. The kernels are made per precision (``wp.float32`` or
``wp.float64``) by :func:`step_kernel`; they may run in place (``*_in`` and ``*_out`` the same
arrays) because each thread reads a particle before it writes it.
"""


import functools

import warp as wp

from ..core.arith import madd, norm2, rsqrt
from ..core.factory import kernel_factory
from ..core.layout import particle
from ..core.root_path import root_on_path

CORRECTIONS = ("prior", "posterior")

#: ``a`` of the push scaling ``max(1 - a m, 0)`` (:func:`carried_func`): a follower's push on its
#: leader is gone once it moved ``1 / a`` of a segment in the step. 1.5 from folded, fast strands
#: (``python scripts/push_scale_study.py``, docs/accuracy/push-scale.md: 15 starts, 6 substep counts):
#: the strand-runs the energy monitor flags fell from 36 at ``a = 1`` to 3, near the floor of
#: dropping every push, and an inverted chain keeps its first-order convergence (tests/test_dftl_folded.py).
PUSH_MOTION_SCALE = 1.5

#: Module options of the step kernels and of the fused kernels (:mod:`.fused`). Floating-point
#: contraction (FMA) is off so that both compute each value with the same roundings and agree
#: bitwise on every device; the step is memory-bound, so contraction buys no speed here.
STEP_MODULE_OPTIONS = {"fuse_fp": False}

#: CUDA launch bounds (threads per block, blocks per SM) of the bare step kernels, by precision.
#: Chosen from H200 probe runs (2026-11-21; resulting figures in docs/benchmarks.md): with the
#: bound the compiler keeps more loads in flight (float32 prior: 88% of the copy bandwidth
#: instead of 81%; float64: 92% instead of 90%).
#: Launch these kernels with Warp's default block of 256 threads.
STEP_LAUNCH_BOUNDS = {wp.float32: (256, 6), wp.float64: (256, 4)}


@functools.cache
def follow_func(scalar):
    """The follow-the-leader projection for ``scalar`` precision (cached ``wp.func``)."""
    vec3 = wp.types.vector(3, scalar)
    # relative length below which a prediction is treated as degenerate (no usable direction)
    degenerate = 1.0e-6 if scalar == wp.float32 else 1.0e-12
    # float32 tests the scale factor rest / |d| itself, after its reciprocal square root (one
    # instruction on CUDA); float64 tests |d|^2 first and takes the costlier root only past it
    # (on the H200 that keeps the fused float64 kernel 1.3x faster)
    scale_test = scalar == wp.float32

    @wp.func
    def follow(leader: vec3, predicted: vec3, rest: scalar, old_leader: vec3, old_self: vec3):
        """New position of a follower: ``rest`` away from ``leader``, towards ``predicted``.

        A degenerate prediction (within ``rest * degenerate`` of the leader, or on it) keeps the
        segment's previous direction, ``old_self - old_leader``; if that too is degenerate, the
        strand's +x axis is used. float32 tests ``rest / |d| < 1 / degenerate`` (infinite or NaN
        when ``d`` vanishes); float64 ``|d|^2 > max((rest * degenerate)^2, 1e-30)``.
        """
        d = predicted - leader
        d2 = norm2(d)
        if wp.static(scale_test):
            scale = rest * rsqrt(d2)
            if scale < scalar(1.0 / degenerate):
                return madd(scale, d, leader)
        else:
            tol = rest * scalar(degenerate)
            if d2 > wp.max(tol * tol, scalar(1.0e-30)):
                return madd(rest * rsqrt(d2), d, leader)
        d = old_self - old_leader
        d2 = norm2(d)
        if d2 > scalar(1.0e-30):
            return madd(rest * rsqrt(d2), d, leader)
        return leader + vec3(rest, scalar(0.0), scalar(0.0))

    return follow


@functools.cache
def carried_func(scalar, scale_pushes: bool = True):
    """The correction a follower hands its leader, for ``scalar`` precision (cached ``wp.func``);
    ``scale_pushes=False``: the paper's ``x - p`` whole (the kernels of before 2026-11-28, for their
    speed: docs/accuracy/folded.md)."""
    vec3 = wp.types.vector(3, scalar)
    push_motion_scale = PUSH_MOTION_SCALE   # read when the kernels are built (studies change it)
    if not scale_pushes:

        @wp.func
        def carried_whole(x: vec3, p: vec3, leader: vec3, x_old: vec3, rest: scalar):
            """``x - p`` (``leader``, ``x_old`` and ``rest`` unused)."""
            return x - p

        return carried_whole

    @wp.func
    def carried(x: vec3, p: vec3, leader: vec3, x_old: vec3, rest: scalar):
        """``x - p`` of a follower now at ``x`` (predicted ``p``, before the step at ``x_old``)
        behind ``leader``: whole where the link pulls it toward the leader; where the link pushes it
        away, times ``max(1 - a |x - x_old| / rest, 0)``, ``a`` :data:`PUSH_MOTION_SCALE` (none once
        it moved ``1 / a`` of a segment in the step).
        A push is a prediction within ``rest`` of the leader, ``|p - leader|^2 < rest^2``: the
        compiler shares ``|p - leader|^2`` with :func:`follow_func`'s, so a sweep without pushes
        pays one multiply and a compare (on the H200 the test ``(x - p) . (x - leader) > 0``, the
        same in exact arithmetic, cost the fused substeps more: docs/benchmarks.md).
        The ratio is ``u rsqrt(u rest^2)`` with ``u = |x - x_old|^2`` (one reciprocal square root, no
        division: the fused kernels have no registers to spare), ``u rest^2`` kept above 1e-30."""
        c = x - p
        if norm2(p - leader) < rest * rest:
            moved2 = norm2(x - x_old)
            motion = moved2 * rsqrt(wp.max(moved2 * (rest * rest), scalar(1.0e-30)))
            c = c * wp.max(scalar(1.0) - scalar(push_motion_scale) * motion, scalar(0.0))
        return c

    return carried


@kernel_factory
def bare_step_kernel(scalar, correction: str, scale_pushes: bool = True):
    """The bare DFTL step kernel (gravity and roots only) for ``scalar`` precision and ``correction``
    form; ``scale_pushes``: :func:`carried_func`."""
    if correction not in CORRECTIONS:
        raise ValueError(f"unknown correction {correction!r}")
    vec3 = wp.types.vector(3, scalar)
    follow = follow_func(scalar)
    carried = carried_func(scalar, scale_pushes)
    bounds = STEP_LAUNCH_BOUNDS.get(scalar)

    if correction == "prior":

        @wp.kernel(enable_backward=False, module="unique", module_options=STEP_MODULE_OPTIONS, launch_bounds=bounds)
        def dftl_step(
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
            inv_dt = scalar(1.0) / dt
            gdt2 = gravity * (dt * dt)
            k = particle(base, stride, 0)
            root = root_on_path(root_start[s], root_end[s] - root_start[s], root_deviation_start[s],
                                root_deviation_end[s], root_alpha)
            leader_old = positions_in[k]
            positions_out[k] = root
            velocities_out[k] = (root - leader_old) * inv_dt
            corrections_out[k] = vec3()
            leader = root
            for i in range(1, n):
                k = particle(base, stride, i)
                x_old = positions_in[k]
                p = madd(dt, velocities_in[k], x_old) + gdt2
                if i + 1 < n:
                    p = madd(-damping, corrections_in[particle(base, stride, i + 1)], p)
                rest = rest_lengths[k]
                x = follow(leader, p, rest, leader_old, x_old)
                positions_out[k] = x
                velocities_out[k] = (x - x_old) * inv_dt
                corrections_out[k] = carried(x, p, leader, x_old, rest)
                leader = x
                leader_old = x_old

        return dftl_step

    @wp.kernel(enable_backward=False, module="unique", module_options=STEP_MODULE_OPTIONS, launch_bounds=bounds)
    def dftl_step_posterior(
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
        gdt2 = gravity * (dt * dt)
        k = particle(base, stride, 0)
        root = root_on_path(root_start[s], root_end[s] - root_start[s], root_deviation_start[s],
                            root_deviation_end[s], root_alpha)
        leader_old = positions_in[k]
        positions_out[k] = root
        velocities_out[k] = (root - leader_old) * inv_dt
        leader = root
        k_prev = k
        for i in range(1, n):
            k = particle(base, stride, i)
            x_old = positions_in[k]
            p = madd(dt, velocities_in[k], x_old) + gdt2
            rest = rest_lengths[k]
            x = follow(leader, p, rest, leader_old, x_old)
            positions_out[k] = x
            if i > 1:
                # the leader's velocity, now that this particle's correction is known
                velocities_out[k_prev] = madd(-(damping * inv_dt), carried(x, p, leader, x_old, rest),
                                              (leader - leader_old) * inv_dt)
            leader = x
            leader_old = x_old
            k_prev = k
        if n > 1:
            velocities_out[k_prev] = (leader - leader_old) * inv_dt

    return dftl_step_posterior
