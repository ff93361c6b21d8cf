"""Pipelined substeps: ``K`` prior-form DFTL substeps in one launch, one *lane* per substep.

The follow-the-leader sweep is sequential along a strand, but substep ``j`` at particle ``i``
only needs substep ``j - 1`` to be done with particles ``i`` and ``i + 1`` (the prior form's
prediction subtracts the follower's previous correction). So ``K`` lanes run the ``K`` substeps
as a wavefront over a *stream* of particles (the strands of a group, one after another; group
``g`` of ``G`` streams strands ``g, g + G, g + 2 G, ...`` of a run of strands with equal vertex
count ``n``). Lane ``j`` sweeps stream particle ``q`` at time ``t = q + 2 j``; when it has swept
``q`` it knows the correction of ``q``, so it hands particle ``q - 1`` to lane ``j + 1``:

- ``x``: the position lane ``j`` gave it (m),
- ``b``: its prediction for substep ``j + 1``, ``x + dt v + dt^2 g - s c_q`` (m),
- ``r``: its rest length (m);

a root hands on ``root_start`` and ``root_end - root_start`` instead, from which every lane
places it on the frame's root path at its own ``alpha = (j + 1) / K`` (and finds where the
previous lane put it), :func:`~dftl_warp.kernels.core.root_path.root_on_path`. The path's
deviations (the Control's) come as two more arguments after the root targets, read by each lane
from global memory when it reaches a root (two vectors per strand and lane: 1.2x the kernel's time
on an H200, docs/benchmarks.md); both kernels are specialised on ``root_path`` and never read them
for the linear path.

Lane 0 takes particles from global memory, lane ``K - 1`` writes them back: global memory is read
and written once per launch, and no lane holds more than two particles, whatever the strand
length. The arithmetic is that of :mod:`.ftl`'s prior step kernel operation for operation
(:func:`pipeline_funcs`: ``as_handed``, ``sweep_particle``, ``handover``), so the results equal
the unfused path bitwise on one device.

Only the hand-over depends on the device:

- :func:`pipelined_kernel` (CUDA): a group's ``K`` lanes are neighbouring threads of a warp and
  hand over with ``__shfl_up_sync``. The lanes also load the stream one block of ``K`` particles
  ahead, one particle each, and pass lane 0 its particle with ``__shfl_sync``, so that a load's
  latency is hidden behind ``K`` sweeps. Lanes sweep before and after the stream too, on values
  nobody uses, instead of branching: only the stores check the stream's bounds.
- :func:`pipelined_serial_kernel` (any device, the CPU in tests): one thread runs a group's lanes
  in turn, last lane first, the hand-over in a scratch array. Lane 0 loads each particle when it
  needs it.
"""

import functools

import warp as wp

from ..core.arith import madd
from ..core.factory import kernel_factory
from .ftl import STEP_MODULE_OPTIONS, carried_func, follow_func
from ..core.layout import particle
from ..core.root_path import root_on_path

#: substeps per launch (lanes per group) of the CUDA kernel: a group must fit a warp evenly
CUDA_LANES = (2, 4, 8, 16, 32)

_SHUFFLE_UP = """
#if defined(__CUDA_ARCH__)
return __shfl_up_sync(mask, v, 1, width);
#else
return v;
#endif
"""
_SHUFFLE_FROM = """
#if defined(__CUDA_ARCH__)
return __shfl_sync(mask, v, lane, width);
#else
return v;
#endif
"""


@wp.func_native(_SHUFFLE_UP)
def shuffle_up(v: wp.float32, mask: wp.uint32, width: wp.int32) -> wp.float32: ...


@wp.func_native(_SHUFFLE_UP)
def shuffle_up(v: wp.float64, mask: wp.uint32, width: wp.int32) -> wp.float64: ...  # noqa: F811


@wp.func_native(_SHUFFLE_FROM)
def shuffle_from(v: wp.float32, lane: wp.int32, mask: wp.uint32, width: wp.int32) -> wp.float32: ...


@wp.func_native(_SHUFFLE_FROM)
def shuffle_from(v: wp.float64, lane: wp.int32, mask: wp.uint32, width: wp.int32) -> wp.float64: ...  # noqa: F811


@functools.cache
def pipeline_funcs(scalar, scale_pushes: bool = True):
    """The per-particle functions both kernels share, for ``scalar`` precision.

    A run's strands are ``first + r`` for ``r`` in ``[0, strands)``; strand ``r``'s particle ``i``
    lives at ``particle(run_strand_base(run_base, r, strand_step, chunk), stride, i)``: runs of
    equal vertex counts are affine in ``r`` within chunks of 32 strands, ``chunk`` strand steps
    apart (32 unless the layout interleaves state vectors; the host checks it)."""
    vec3 = wp.types.vector(3, scalar)
    follow = follow_func(scalar)
    carried = carried_func(scalar, scale_pushes)

    @wp.func
    def run_strand_base(run_base: wp.int32, r: wp.int32, strand_step: wp.int32, chunk: wp.int32):
        """First slot of run strand ``r``."""
        return run_base + ((r >> 5) * chunk + (r & 31)) * strand_step

    @wp.func
    def stream_slot(q: wp.int32, n: wp.int32, group: wp.int32, groups: wp.int32, run_base: wp.int32,
                    strand_step: wp.int32, chunk: wp.int32, stride: wp.int32):
        """Run strand, vertex index and slot of stream particle ``q`` of ``group``."""
        m = q / n
        i = q - m * n
        r = group + m * groups
        return r, i, particle(run_strand_base(run_base, r, strand_step, chunk), stride, i)

    @wp.func
    def as_handed(i: wp.int32, n: wp.int32, x: vec3, v: vec3, follower_correction: vec3, rest: scalar,
                  root_start: vec3, root_end: vec3, dt: scalar, damping: scalar, gdt2: vec3):
        """A particle as the launch found it, in hand-over form ``(x, b, r, root)``: a follower
        carries its position, first prediction and rest length; a root (``i = 0``) its position,
        ``root_end - root_start`` in ``b`` and ``root_start`` in ``root``."""
        p = madd(dt, v, x) + gdt2
        if i + 1 < n:
            p = madd(-damping, follower_correction, p)
        b = wp.where(i == 0, root_end - root_start, p)
        return x, b, rest, root_start

    @wp.func
    def load_handed(r: wp.int32, i: wp.int32, k: wp.int32, n: wp.int32, first: wp.int32, stride: wp.int32,
                    root_start: wp.array(dtype=vec3), root_end: wp.array(dtype=vec3),
                    rest_lengths: wp.array(dtype=scalar), positions: wp.array(dtype=vec3),
                    velocities: wp.array(dtype=vec3), corrections: wp.array(dtype=vec3), dt: scalar,
                    damping: scalar, gdt2: vec3):
        """Vertex ``i`` of run strand ``r`` at slot ``k`` (:func:`stream_slot`) from global memory,
        in hand-over form (:func:`as_handed`)."""
        return as_handed(i, n, positions[k], velocities[k], corrections[k + wp.where(i + 1 < n, stride, 0)],
                         rest_lengths[k], root_start[first + r], root_end[first + r], dt, damping, gdt2)

    @wp.func
    def sweep_particle(i: wp.int32, j: wp.int32, substeps: wp.int32, x_in: vec3, b_in: vec3, rest: scalar,
                       root_in: vec3, deviation_start: vec3, deviation_end: vec3, leader: vec3, leader_old: vec3,
                       dt: scalar, inv_dt: scalar, gdt2: vec3):
        """Substep ``j`` of ``substeps`` on particle ``i`` as handed over (:func:`as_handed`; after
        lane 0 a root arrives as ``(root_start, root_end - root_start)``; a root's path deviations
        are its strand's, zero for the linear path).

        Returns the new position, velocity and correction, the position before this substep, and
        the particle in hand-over form for the next lane: a follower's position and next prediction
        (before its follower's correction is subtracted), a root's ``root_start`` and
        ``root_end - root_start``."""
        if i == 0:
            # the root at alpha = (j + 1) / K; it was at alpha = j / K (lane 0: where the launch found it)
            root_start = wp.where(j == 0, root_in, x_in)
            x = root_on_path(root_start, b_in, deviation_start, deviation_end, scalar(j + 1) / scalar(substeps))
            x_old = x_in
            if j > 0:
                x_old = root_on_path(root_start, b_in, deviation_start, deviation_end, scalar(j) / scalar(substeps))
            v = (x - x_old) * inv_dt
            return x, v, vec3(), x_old, root_start, b_in
        x = follow(leader, b_in, rest, leader_old, x_in)
        v = (x - x_in) * inv_dt
        return x, v, carried(x, b_in, leader, x_in, rest), x_in, x, madd(dt, v, x) + gdt2

    @wp.func
    def handover(i: wp.int32, b: vec3, follower_correction: vec3, damping: scalar):
        """The hand-over ``b`` of particle ``q - 1`` once particle ``q`` (vertex ``i``) is swept:
        minus ``s c_q`` if ``q - 1`` is a follower of ``q``'s strand (``i >= 2``)."""
        if i >= 2:
            return madd(-damping, follower_correction, b)
        return b

    return run_strand_base, stream_slot, as_handed, load_handed, sweep_particle, handover


def _shuffles(scalar):
    vec3 = wp.types.vector(3, scalar)

    @wp.func
    def vec_up(v: vec3, mask: wp.uint32, width: wp.int32):
        return vec3(shuffle_up(v[0], mask, width), shuffle_up(v[1], mask, width), shuffle_up(v[2], mask, width))

    @wp.func
    def vec_from(v: vec3, lane: wp.int32, mask: wp.uint32, width: wp.int32):
        return vec3(shuffle_from(v[0], lane, mask, width), shuffle_from(v[1], lane, mask, width),
                    shuffle_from(v[2], lane, mask, width))

    return vec_up, vec_from


@kernel_factory
def pipelined_kernel(scalar, substeps: int, root_path: bool = True, scale_pushes: bool = True):
    """CUDA kernel: ``substeps`` prior-form substeps of one run of ``strands`` strands of ``n``
    vertices, in ``groups`` groups (at most ``strands``) of ``substeps`` neighbouring threads.
    Launch with ``dim = groups * substeps`` and a block of a multiple of 32 threads. It takes the
    roots' path deviations after ``root_end`` (module docstring); ``root_path=False`` never reads
    them (the linear path: a Control without root velocities), which the uncoalesced per-lane reads
    cost about a fifth of this kernel's throughput on an H200 (docs/benchmarks.md)."""
    K = int(substeps)
    if K not in CUDA_LANES:
        raise ValueError(f"pipelined substeps must be one of {CUDA_LANES}, got {substeps}")
    vec3 = wp.types.vector(3, scalar)
    funcs = pipeline_funcs(scalar, scale_pushes)
    run_strand_base, stream_slot, as_handed, load_handed, sweep_particle, handover = funcs
    vec_up, vec_from = _shuffles(scalar)
    group_mask = (1 << K) - 1 if K < 32 else 0xFFFFFFFF
    # the K sweeps of a block stay a loop: unrolled, the compiler hoists the block's independent
    # shuffles and runs out of registers (255 and spills in a build for K = 8; 96 as a loop)
    options = {**STEP_MODULE_OPTIONS, "max_unroll": 1}

    @wp.kernel(enable_backward=False, module="unique", module_options=options)
    def dftl_pipelined(
        first: wp.int32,
        strands: wp.int32,
        groups: wp.int32,
        n: wp.int32,
        run_base: wp.int32,
        strand_step: wp.int32,
        chunk: wp.int32,
        stride: wp.int32,
        root_start: wp.array(dtype=vec3),
        root_end: wp.array(dtype=vec3),
        root_deviation_start: wp.array(dtype=vec3),
        root_deviation_end: wp.array(dtype=vec3),
        rest_lengths: wp.array(dtype=scalar),
        gravity: vec3,
        dt: scalar,
        damping: scalar,
        positions: wp.array(dtype=vec3),
        velocities: wp.array(dtype=vec3),
        corrections: wp.array(dtype=vec3),
    ):
        tid = wp.tid()
        group = tid / wp.static(K)
        j = tid - group * wp.static(K)
        mask = wp.uint32(wp.static(group_mask)) << wp.uint32((tid & 31) - j)
        inv_dt = scalar(1.0) / dt
        gdt2 = gravity * (dt * dt)
        last = j == wp.static(K - 1)
        stream = ((strands - group + groups - 1) / groups) * n
        # the lane's share of the stream, one block of K particles ahead: loads are unconditional
        # (clamped to the stream) so that nothing waits for them before the block's end
        r, vi, k = stream_slot(wp.min(j, stream - 1), n, group, groups, run_base, strand_step, chunk, stride)
        hand_x, hand_b, hand_r, hand_root = load_handed(r, vi, k, n, first, stride, root_start, root_end,
                                                        rest_lengths, positions, velocities, corrections,
                                                        dt, damping, gdt2)
        # the lane's sweep: stream particle q = t - 2 j, vertex i of the lane's m-th strand. Lanes
        # sweep before and after the stream too (on values nobody uses) rather than branch: only
        # the stores check that q is in the stream
        i = (n - (2 * j) % n) % n
        m = (-2 * j - i) / n
        leader = vec3()
        leader_old = vec3()
        keep_x = vec3()
        keep_b = vec3()
        keep_r = scalar(0.0)
        send_x = vec3()
        send_b = vec3()
        send_r = scalar(0.0)
        for block in range((stream + wp.static(3 * K - 2)) / wp.static(K)):
            # the next block's loads now, their conversion (load_handed's as_handed) at the block's end
            r, vi, k = stream_slot(wp.min((block + 1) * wp.static(K) + j, stream - 1), n, group, groups,
                                   run_base, strand_step, chunk, stride)
            raw_x = positions[k]
            raw_v = velocities[k]
            raw_c = corrections[k + wp.where(vi + 1 < n, stride, 0)]
            raw_r = rest_lengths[k]
            raw_root_start = root_start[first + r]
            raw_root_end = root_end[first + r]
            for u in range(wp.static(K)):
                q = block * wp.static(K) + u - 2 * j
                # particle q: lane 0 takes it from the block's lane u, the others from lane j - 1
                in_x = vec_up(send_x, mask, wp.static(K))
                in_b = vec_up(send_b, mask, wp.static(K))
                in_r = shuffle_up(send_r, mask, wp.static(K))
                from_x = vec_from(hand_x, u, mask, wp.static(K))
                from_b = vec_from(hand_b, u, mask, wp.static(K))
                from_r = shuffle_from(hand_r, u, mask, wp.static(K))
                in_root = vec_from(hand_root, u, mask, wp.static(K))
                if j == 0:
                    in_x = from_x
                    in_b = from_b
                    in_r = from_r
                d0 = vec3()
                d1 = vec3()
                if wp.static(root_path):
                    if i == 0:   # the lane's strand (clamped: lanes also sweep before and after the stream)
                        rs = first + wp.clamp(group + m * groups, 0, strands - 1)
                        d0 = root_deviation_start[rs]
                        d1 = root_deviation_end[rs]
                x, v, c, x_old, hx, hb = sweep_particle(i, j, wp.static(K), in_x, in_b, in_r, in_root, d0, d1, leader,
                                                        leader_old, dt, inv_dt, gdt2)
                if last and q >= 0 and q < stream:
                    kq = particle(run_strand_base(run_base, group + m * groups, strand_step, chunk), stride, i)
                    positions[kq] = x
                    velocities[kq] = v
                    corrections[kq] = c
                # hand particle q - 1 on, now that its follower's correction is known (q = stream:
                # the stream's last particle, a tip, i = 0 again: nothing subtracted)
                send_x = keep_x
                send_b = handover(i, keep_b, c, damping)
                send_r = keep_r
                keep_x = hx
                keep_b = hb
                keep_r = in_r
                leader = x
                leader_old = x_old
                i += 1
                if i == n:
                    i = 0
                    m += 1
            hand_x, hand_b, hand_r, hand_root = as_handed(vi, n, raw_x, raw_v, raw_c, raw_r, raw_root_start,
                                                          raw_root_end, dt, damping, gdt2)

    return dftl_pipelined


@kernel_factory
def pipelined_serial_kernel(scalar, root_path: bool = True, scale_pushes: bool = True):
    """Any device: the pipelined substeps with one thread per group running its ``substeps``
    lanes in turn, last lane first. Launch with ``dim = groups``; ``lane_vectors``
    (``groups * substeps`` x 6) and ``lane_scalars`` (x 2) are scratch. The kernel takes the
    roots' path deviations after ``root_end`` (module docstring); ``root_path=False`` never reads
    them (the linear path), as :func:`pipelined_kernel`."""
    vec3 = wp.types.vector(3, scalar)
    funcs = pipeline_funcs(scalar, scale_pushes)
    run_strand_base, stream_slot, as_handed, load_handed, sweep_particle, handover = funcs
    ROOT_PATH = bool(root_path)

    @wp.kernel(enable_backward=False, module="unique", module_options=STEP_MODULE_OPTIONS)
    def dftl_pipelined_serial(
        first: wp.int32,
        strands: wp.int32,
        groups: wp.int32,
        n: wp.int32,
        run_base: wp.int32,
        strand_step: wp.int32,
        chunk: wp.int32,
        stride: wp.int32,
        root_start: wp.array(dtype=vec3),
        root_end: wp.array(dtype=vec3),
        root_deviation_start: wp.array(dtype=vec3),
        root_deviation_end: wp.array(dtype=vec3),
        rest_lengths: wp.array(dtype=scalar),
        gravity: vec3,
        dt: scalar,
        damping: scalar,
        substeps: wp.int32,
        lane_vectors: wp.array2d(dtype=vec3),
        lane_scalars: wp.array2d(dtype=scalar),
        positions: wp.array(dtype=vec3),
        velocities: wp.array(dtype=vec3),
        corrections: wp.array(dtype=vec3),
    ):
        group = wp.tid()
        inv_dt = scalar(1.0) / dt
        gdt2 = gravity * (dt * dt)
        stream = ((strands - group + groups - 1) / groups) * n
        # lane_vectors: leader, leader_old, keep_x, keep_b, send_x, send_b; lane_scalars: keep_r, send_r
        for j in range(substeps):
            for f in range(6):
                lane_vectors[group * substeps + j, f] = vec3()
            lane_scalars[group * substeps + j, 0] = scalar(0.0)
            lane_scalars[group * substeps + j, 1] = scalar(0.0)
        for t in range(stream + 2 * substeps - 1):
            for jj in range(substeps):
                j = substeps - 1 - jj  # last lane first: lane j - 1 still holds what it sent at t - 1
                row = group * substeps + j
                q = t - 2 * j
                if q >= 0 and q < stream:
                    r, i, k = stream_slot(q, n, group, groups, run_base, strand_step, chunk, stride)
                    if j == 0:
                        in_x, in_b, in_r, in_root = load_handed(r, i, k, n, first, stride, root_start, root_end,
                                                                rest_lengths, positions, velocities, corrections,
                                                                dt, damping, gdt2)
                    else:
                        in_x = lane_vectors[row - 1, 4]
                        in_b = lane_vectors[row - 1, 5]
                        in_r = lane_scalars[row - 1, 1]
                        in_root = vec3()
                    d0 = vec3()
                    d1 = vec3()
                    if wp.static(ROOT_PATH):
                        if i == 0:
                            d0 = root_deviation_start[first + r]
                            d1 = root_deviation_end[first + r]
                    x, v, c, x_old, hx, hb = sweep_particle(i, j, substeps, in_x, in_b, in_r, in_root, d0, d1,
                                                            lane_vectors[row, 0], lane_vectors[row, 1], dt,
                                                            inv_dt, gdt2)
                    if j == substeps - 1:
                        positions[k] = x
                        velocities[k] = v
                        corrections[k] = c
                    lane_vectors[row, 4] = lane_vectors[row, 2]
                    lane_vectors[row, 5] = handover(i, lane_vectors[row, 3], c, damping)
                    lane_scalars[row, 1] = lane_scalars[row, 0]
                    lane_vectors[row, 2] = hx
                    lane_vectors[row, 3] = hb
                    lane_scalars[row, 0] = in_r
                    lane_vectors[row, 0] = x
                    lane_vectors[row, 1] = x_old
                elif q == stream:
                    lane_vectors[row, 4] = lane_vectors[row, 2]
                    lane_vectors[row, 5] = lane_vectors[row, 3]
                    lane_scalars[row, 1] = lane_scalars[row, 0]

    return dftl_pipelined_serial
