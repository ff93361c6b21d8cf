"""Fused substeps: ``substeps`` DFTL steps in one launch, each strand's state kept on chip.

One kernel per strand *capacity* ``N`` (a compile-time constant). Each thread keeps two rows per
particle on chip, in per-thread matrices addressed by unrolled constant indices (registers):

- ``x``: its position;
- ``b``: its next prediction, ``x + dt v + dt^2 g`` (prior form: minus ``s`` times its follower's
  correction, subtracted as soon as the follower has been swept).

That is 6 values per particle instead of the 9 (x, v, correction) a step reads, plus its rest
length up to ``REST_ON_CHIP_MAX`` vertices (longer strands re-read it every substep), which keeps
strands of 32 vertices on chip: in registers, the rest lengths (and root targets) of float32
32-vertex strands in shared memory (``REST_IN_SHARED``). Velocities and corrections are written to global memory only
by the last substep; positions once at the end. Global memory is read and written once per
launch instead of once per substep.

The arithmetic is that of :mod:`.ftl`'s step kernels, operation for operation (only computed at
another point of the loop), so the results are identical to the unfused path. Roots move on the
frame's root path inside the loop (:func:`~dftl_warp.kernels.core.root_path.root_on_path`, the
unfused kernels' helper): substep ``j`` places them at ``alpha = (j + 1) / substeps``.

A strand with fewer than ``N`` vertices may use a capacity-``N`` kernel (``exact=False``): rows
past its count are skipped. ``exact=True`` kernels serve strands of exactly ``N`` vertices and
compile the guards away.
"""

import functools

import warp as wp

from ..core.arith import madd
from ..core.factory import kernel_factory
from .ftl import CORRECTIONS, STEP_MODULE_OPTIONS, carried_func, follow_func
from ..core.layout import particle
from ..core.root_path import root_on_path


#: CUDA launch bounds (threads per block, blocks per SM) of the fused kernels, by precision and
#: capacity, chosen from H200 probe runs (2026-11-21; resulting figures in docs/benchmarks.md):
#: fewer registers for more resident warps where that is faster. Others run Warp's default block of 256 threads, unbounded.
FUSED_LAUNCH_BOUNDS = {(wp.float32, 8): (128, 5), (wp.float32, 16): (128, 3), (wp.float32, 24): (128, 2)}


#: longest capacity whose rest lengths are kept on chip; longer ones re-read them every substep
#: (L1 hits, but each adds its latency to the sweep: in an H200 probe run, k = 8, keeping them on
#: chip made 24-vertex strands 1.5x and 32-vertex strands 1.35x faster)
REST_ON_CHIP_MAX = 32

#: (precision, capacity) whose on-chip rest lengths live in shared memory rather than registers:
#: at 32 vertices the 224 register values per thread spilled; this frees 32 of them (H200 probe
#: runs, 2026-11-21, k = 8: 3.4x -> 3.7-3.8x the per-step floor, bitwise the same results). The
#: root targets and their path's deviations join them (12 registers fewer through the substep
#: loop; 44 slots x 256 threads x 4 B = 44 KiB of the 48 KiB a block may hold statically; the
#: deviations' 12 KiB cost nothing measurable on an H200, docs/benchmarks.md, 2026-11-24).
REST_IN_SHARED = {(wp.float32, 32)}

# A private row of scalars per thread in shared memory, laid out [slot][thread] so that a warp
# touches 32 consecutive words. Volatile: the compiler must not hoist the loads out of the
# substep loop back into registers. On the CPU, where Warp runs a launch's threads one after
# another, one static row serves each thread in turn.
_SHARED_ROW = """
#if defined(__CUDA_ARCH__)
    __shared__ {ctype} rows[{size}];
    volatile {ctype}* at = rows + slot * {block_dim} + threadIdx.x;
#else
    static {ctype} rows[{slots}];
    {ctype}* at = rows + slot;
#endif
    if (store) {{
        *at = value;
        return value;
    }}
    return *at;
"""


@functools.cache
def shared_row_func(scalar, slots: int, block_dim: int):
    """``row(slot, value, store)``: read (``store == 0``) or write (``store == 1``) scalar
    ``slot`` of the calling thread's private shared-memory row; launch with ``block_dim``."""
    ctype = {wp.float32: "float", wp.float64: "double"}[scalar]
    snippet = _SHARED_ROW.format(ctype=ctype, size=slots * block_dim, block_dim=block_dim, slots=slots)

    @wp.func_native(snippet)
    def row(slot: wp.int32, value: scalar, store: wp.int32) -> scalar: ...

    return row


def fused_block_dim(scalar, capacity: int) -> int:
    """Threads per block to launch the fused kernel of ``scalar`` precision and ``capacity`` with."""
    bounds = FUSED_LAUNCH_BOUNDS.get((scalar, int(capacity)))
    return bounds[0] if bounds else 256


@kernel_factory
def fused_step_kernel(scalar, correction: str, capacity: int, exact: bool = False, scale_pushes: bool = True):
    """Kernel advancing strands of at most (``exact``: exactly) ``capacity`` vertices by
    ``substeps`` steps (cached). Launch with ``dim`` = number of strands in the run; thread ``t``
    advances device strand ``first_strand + t``."""
    if correction not in CORRECTIONS:
        raise ValueError(f"unknown correction {correction!r}")
    N = int(capacity)
    exact = bool(exact)
    vec3 = wp.types.vector(3, scalar)
    rows = wp.types.matrix(shape=(N, 3), dtype=scalar)
    column = wp.types.vector(N, dtype=scalar)
    follow = follow_func(scalar)
    carried = carried_func(scalar, scale_pushes)
    prior = correction == "prior"
    options = {**STEP_MODULE_OPTIONS, "max_unroll": 4 * N + 16}
    # rest lengths stay on chip up to REST_ON_CHIP_MAX; longer strands re-read them to save registers
    rest_on_chip = N <= REST_ON_CHIP_MAX
    rest_shared = (scalar, N) in REST_IN_SHARED
    if rest_shared:
        # slots 0..N-1: rest lengths; N..N+2: the root's start target; N+3..N+5: its end target;
        # N+6..N+8, N+9..N+11: its path's deviations at the frame's start and end
        rest_row = shared_row_func(scalar, N + 12, fused_block_dim(scalar, N))

        @wp.func
        def row_vec(slot: wp.int32):
            """The vector in shared slots ``slot .. slot + 2``."""
            return vec3(rest_row(slot, scalar(0.0), 0), rest_row(slot + 1, scalar(0.0), 0),
                        rest_row(slot + 2, scalar(0.0), 0))

    @wp.func
    def root_at(alpha: scalar, r0: vec3, r1: vec3, d0: vec3, d1: vec3):
        """The root on its path at ``alpha`` in [0, 1], from the shared row when it holds the
        targets and deviations."""
        if wp.static(rest_shared):
            a = row_vec(N)
            return root_on_path(a, row_vec(N + 3) - a, row_vec(N + 6), row_vec(N + 9), alpha)
        return root_on_path(r0, r1 - r0, d0, d1, alpha)

    @wp.func
    def sweep_prior(leader: vec3, leader_old: vec3, x_old: vec3, p: vec3, rest: scalar, dt: scalar,
                    inv_dt: scalar, gdt2: vec3):
        """One particle of a prior-form sweep: new position, velocity, correction and the
        next substep's prediction (before its follower's correction is subtracted)."""
        xi = follow(leader, p, rest, leader_old, x_old)
        vi = (xi - x_old) * inv_dt
        return xi, vi, carried(xi, p, leader, x_old, rest), madd(dt, vi, xi) + gdt2

    @wp.kernel(enable_backward=False, module="unique", module_options=options,
               launch_bounds=FUSED_LAUNCH_BOUNDS.get((scalar, N)))
    def dftl_fused(
        first_strand: wp.int32,
        strand_base: wp.array(dtype=wp.int32),
        strand_stride: wp.array(dtype=wp.int32),
        strand_count: wp.array(dtype=wp.int32),
        root_start: wp.array(dtype=vec3),
        root_end: wp.array(dtype=vec3),
        root_deviation_start: wp.array(dtype=vec3),
        root_deviation_end: wp.array(dtype=vec3),
        rest_lengths: wp.array(dtype=scalar),
        gravity: vec3,
        dt: scalar,
        damping: scalar,
        substeps: wp.int32,
        positions: wp.array(dtype=vec3),
        velocities: wp.array(dtype=vec3),
        corrections: wp.array(dtype=vec3),
    ):
        s = first_strand + wp.tid()
        if substeps < 1:
            return
        base = strand_base[s]
        stride = strand_stride[s]
        n = wp.where(wp.static(exact), wp.static(N), strand_count[s])
        inv_dt = scalar(1.0) / dt
        gdt2 = gravity * (dt * dt)
        x = rows()
        b = rows()
        rest = column()
        for i in range(wp.static(N)):
            if i < n:
                k = particle(base, stride, i)
                x[i] = positions[k]
                b[i] = madd(dt, velocities[k], x[i]) + gdt2
                if wp.static(rest_shared):
                    rest_row(i, rest_lengths[k], 1)
                elif wp.static(rest_on_chip):
                    rest[i] = rest_lengths[k]
                if wp.static(prior):
                    if i > 0:
                        b[i - 1] = madd(-damping, corrections[k], b[i - 1])
        r0 = root_start[s]
        r1 = root_end[s]
        d0 = root_deviation_start[s]
        d1 = root_deviation_end[s]
        if wp.static(rest_shared):
            # kept in shared memory with the rest lengths: 12 registers fewer through the loop
            for c in range(3):
                rest_row(N + c, r0[c], 1)
                rest_row(N + 3 + c, r1[c], 1)
                rest_row(N + 6 + c, d0[c], 1)
                rest_row(N + 9 + c, d1[c], 1)
        # all substeps but the last: registers only, no global memory
        for j in range(substeps - 1):
            # opaque to the compiler (see the last substep), so rest-length addresses are not hoisted
            base_j = base + wp.int32(scalar(0.0) * x[0][0])
            alpha = scalar(j + 1) / scalar(substeps)
            root = root_at(alpha, r0, r1, d0, d1)
            leader_old = x[0]
            x[0] = root
            leader = root
            for i in range(1, wp.static(N)):
                if i < n:
                    x_old = x[i]
                    p = b[i]
                    if wp.static(rest_shared):
                        rest_i = rest_row(i, scalar(0.0), 0)
                    elif wp.static(rest_on_chip):
                        rest_i = rest[i]
                    else:
                        rest_i = rest_lengths[particle(base_j, stride, i)]
                    if wp.static(prior):
                        xi, vi, ci, bi = sweep_prior(leader, leader_old, x_old, p, rest_i, dt, inv_dt, gdt2)
                        b[i] = bi
                        if i > 1:
                            b[i - 1] = madd(-damping, ci, b[i - 1])
                    else:
                        xi = follow(leader, p, rest_i, leader_old, x_old)
                        if i > 1:
                            v_leader = madd(-(damping * inv_dt), carried(xi, p, leader, x_old, rest_i),
                                            (leader - leader_old) * inv_dt)
                            b[i - 1] = madd(dt, v_leader, leader) + gdt2
                        if i + 1 == n:
                            b[i] = madd(dt, (xi - x_old) * inv_dt, xi) + gdt2
                    x[i] = xi
                    leader = xi
                    leader_old = x_old
        # the last substep writes the state back as it sweeps. Its slots are recomputed from a
        # base the compiler cannot prove equal to the loads' (0 * x is not folded without fast
        # math; int(NaN) is 0): otherwise it keeps every particle's addresses live through the
        # loop, three 64-bit pointers per particle, and runs out of registers.
        base = base + wp.int32(scalar(0.0) * x[0][0])
        root = root_at(scalar(substeps) / scalar(substeps), r0, r1, d0, d1)
        leader_old = x[0]
        positions[base] = root
        velocities[base] = (root - leader_old) * inv_dt
        if wp.static(prior):
            corrections[base] = vec3()
        leader = root
        k_prev = base
        for i in range(1, wp.static(N)):
            if i < n:
                k = particle(base, stride, i)
                x_old = x[i]
                p = b[i]
                if wp.static(rest_shared):
                    rest_i = rest_row(i, scalar(0.0), 0)
                elif wp.static(rest_on_chip):
                    rest_i = rest[i]
                else:
                    rest_i = rest_lengths[k]
                if wp.static(prior):
                    xi, vi, ci, bi = sweep_prior(leader, leader_old, x_old, p, rest_i, dt, inv_dt, gdt2)
                    velocities[k] = vi
                    corrections[k] = ci
                else:
                    xi = follow(leader, p, rest_i, leader_old, x_old)
                    if i > 1:
                        velocities[k_prev] = madd(-(damping * inv_dt), carried(xi, p, leader, x_old, rest_i),
                                                  (leader - leader_old) * inv_dt)
                    if i + 1 == n:
                        velocities[k] = (xi - x_old) * inv_dt
                positions[k] = xi
                leader = xi
                leader_old = x_old
                k_prev = k

    return dftl_fused
