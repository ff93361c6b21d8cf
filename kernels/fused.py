"""Fused substeps: ``substeps`` DFTL steps in one launch, each strand's state kept on chip.

One kernel per strand *capacity* ``N`` (a compile-time constant): the strand's positions,
velocities, carried corrections and rest lengths are loaded once into per-thread matrices whose
rows are addressed by unrolled, constant indices (registers; the compiler spills what does not
fit to local memory), advanced ``substeps`` times, and stored once. Global memory is touched once
per launch instead of once per substep.

The arithmetic is exactly that of :mod:`.ftl`'s step kernels, operation for operation, so the
results are identical to the unfused path. Roots move by linear interpolation inside the loop:
substep ``j`` places them at ``alpha = (j + 1) / substeps``.

A strand with fewer than ``N`` vertices may use a capacity-``N`` kernel: rows past its count are
skipped.
"""

import functools

import warp as wp

from .ftl import CORRECTIONS, follow_func
from .layout import particle


@functools.cache
def fused_step_kernel(scalar, correction: str, capacity: int):
    """Kernel advancing strands of at most ``capacity`` vertices by ``substeps`` steps (cached).

    Launch with ``dim`` = number of strands in the group; thread ``t`` advances device strand
    ``first_strand + t``.
    """
    if correction not in CORRECTIONS:
        raise ValueError(f"unknown correction {correction!r}")
    N = int(capacity)
    vec3 = wp.types.vector(3, scalar)
    rows = wp.types.matrix(shape=(N, 3), dtype=scalar)
    # corrections get one extra, always-zero row so that row i + 1 exists for every i
    rows_c = wp.types.matrix(shape=(N + 1, 3), dtype=scalar)
    column = wp.types.vector(N, dtype=scalar)
    follow = follow_func(scalar)
    prior = correction == "prior"
    options = {"max_unroll": 4 * N + 16}

    @wp.kernel(enable_backward=False, module="unique", module_options=options)
    def dftl_fused(
        first_strand: wp.int32,
        strand_base: wp.array(dtype=wp.int32),
        strand_stride: wp.array(dtype=wp.int32),
        strand_count: wp.array(dtype=wp.int32),
        root_start: wp.array(dtype=vec3),
        root_end: wp.array(dtype=vec3),
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
        base = strand_base[s]
        stride = strand_stride[s]
        n = strand_count[s]
        x = rows()
        v = rows()
        c = rows_c()
        rest = column()
        for i in range(wp.static(N)):
            if i < n:
                k = particle(base, stride, i)
                x[i] = positions[k]
                v[i] = velocities[k]
                rest[i] = rest_lengths[k]
                if wp.static(prior):
                    c[i] = corrections[k]
        inv_dt = scalar(1.0) / dt
        gdt2 = gravity * (dt * dt)
        r0 = root_start[s]
        r1 = root_end[s]
        for j in range(substeps):
            alpha = scalar(j + 1) / scalar(substeps)
            root = r0 + alpha * (r1 - r0)
            leader_old = x[0]
            x[0] = root
            v[0] = (root - leader_old) * inv_dt
            leader = root
            for i in range(1, wp.static(N)):
                if i < n:
                    x_old = x[i]
                    p = x_old + dt * v[i] + gdt2
                    if wp.static(prior):
                        if i + 1 < n:
                            p = p - damping * c[i + 1]
                    xi = follow(leader, p, rest[i], leader_old, x_old)
                    x[i] = xi
                    if wp.static(prior):
                        v[i] = (xi - x_old) * inv_dt
                        c[i] = xi - p
                    else:
                        if i > 1:
                            v[i - 1] = (leader - leader_old) * inv_dt - (damping * inv_dt) * (xi - p)
                        if i + 1 == n:
                            v[i] = (xi - x_old) * inv_dt
                    leader = xi
                    leader_old = x_old
        for i in range(wp.static(N)):
            if i < n:
                k = particle(base, stride, i)
                positions[k] = x[i]
                velocities[k] = v[i]
                if wp.static(prior):
                    if i == 0:
                        corrections[k] = vec3()
                    else:
                        corrections[k] = c[i]

    return dftl_fused
