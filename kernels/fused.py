"""Fused substeps: ``substeps`` DFTL steps in one launch, each strand's state kept on chip.

One kernel per strand *capacity* ``N`` (a compile-time constant). Each thread keeps two rows per
particle on chip, in per-thread matrices addressed by unrolled constant indices (registers):

- ``x``: its position;
- ``b``: its next prediction, ``x + dt v + dt^2 g`` (prior form: minus ``s`` times its follower's
  correction, subtracted as soon as the follower has been swept).

That is 6 values per particle instead of the 9 (x, v, correction) a step reads, which keeps
strands of 32 vertices in registers. Velocities and corrections are written to global memory only
by the last substep; positions once at the end. Global memory is read and written once per
launch instead of once per substep.

The arithmetic is that of :mod:`.ftl`'s step kernels, operation for operation (only computed at
another point of the loop), so the results are identical to the unfused path. Roots move by
linear interpolation inside the loop: substep ``j`` places them at ``alpha = (j + 1) / substeps``.

A strand with fewer than ``N`` vertices may use a capacity-``N`` kernel (``exact=False``): rows
past its count are skipped. ``exact=True`` kernels serve strands of exactly ``N`` vertices and
compile the guards away.
"""

import functools

import warp as wp

from .ftl import CORRECTIONS, STEP_MODULE_OPTIONS, follow_func
from .layout import particle


@functools.cache
def fused_step_kernel(scalar, correction: str, capacity: int, exact: bool = False):
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
    prior = correction == "prior"
    rest_on_chip = N <= 16  # longer strands re-read rest lengths (cached) to save registers
    options = {**STEP_MODULE_OPTIONS, "max_unroll": 4 * N + 16}

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
                b[i] = x[i] + dt * velocities[k] + gdt2
                if wp.static(rest_on_chip):
                    rest[i] = rest_lengths[k]
                if wp.static(prior):
                    if i > 0:
                        b[i - 1] = b[i - 1] - damping * corrections[k]
        r0 = root_start[s]
        r1 = root_end[s]
        root_velocity = vec3()
        for j in range(substeps):
            last = j + 1 == substeps
            alpha = scalar(j + 1) / scalar(substeps)
            root = r0 + alpha * (r1 - r0)
            leader_old = x[0]
            x[0] = root
            root_velocity = (root - leader_old) * inv_dt
            leader = root
            k_prev = base
            for i in range(1, wp.static(N)):
                if i < n:
                    k = particle(base, stride, i)
                    x_old = x[i]
                    p = b[i]
                    if wp.static(rest_on_chip):
                        xi = follow(leader, p, rest[i], leader_old, x_old)
                    else:
                        xi = follow(leader, p, rest_lengths[k], leader_old, x_old)
                    x[i] = xi
                    if wp.static(prior):
                        vi = (xi - x_old) * inv_dt
                        ci = xi - p
                        b[i] = xi + dt * vi + gdt2
                        if i > 1:
                            b[i - 1] = b[i - 1] - damping * ci
                        if last:
                            velocities[k] = vi
                            corrections[k] = ci
                    else:
                        if i > 1:
                            v_leader = (leader - leader_old) * inv_dt - (damping * inv_dt) * (xi - p)
                            b[i - 1] = leader + dt * v_leader + gdt2
                            if last:
                                velocities[k_prev] = v_leader
                        if i + 1 == n:
                            vi = (xi - x_old) * inv_dt
                            b[i] = xi + dt * vi + gdt2
                            if last:
                                velocities[k] = vi
                    leader = xi
                    leader_old = x_old
                    k_prev = k
        for i in range(wp.static(N)):
            if i < n:
                positions[particle(base, stride, i)] = x[i]
        if substeps > 0:
            velocities[base] = root_velocity
            if wp.static(prior):
                corrections[base] = vec3()

    return dftl_fused
