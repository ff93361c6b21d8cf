"""On-chip RATTLE: the frame's substeps with the whole strand in thread-local storage.

The arithmetic of :mod:`.rattle` (the global-memory kernel), operation for operation, for strands of
at most ``N`` vertices (``N``, the *capacity*, a compile-time constant: 8, 16, 24 or 32). Every
loop over the strand is unrolled over ``N`` (rows past the strand's count are skipped), so the
per-particle rows are per-thread fixed-size matrices and vectors addressed by constant indices: in
registers where they fit, in the thread's local memory (L1) where the compiler spills them.
Global memory is read once per launch (positions, velocities, rest lengths) and written once
(positions, velocities, two statistics per strand), instead of ``2 * iterations + 5`` scratch
sweeps per substep.

Per particle the thread holds ``x`` and ``lo`` (the position as the unevaluated sum ``x + lo``),
``v``, the multipliers ``mu`` and the Thomas coefficients ``cp``/``dp``, and the rest length:
13 values (52 bytes in float32, 1.6 KiB per 32-vertex strand). The prediction ``q`` of the
global kernel is not stored: ``q_i = h (v_i + h/2 g)`` is recomputed where it is read (the same
operations on the same values, so the same bits), and the Newton candidate
``q_i + mu_i r_i - mu_{i+1} r_{i+1}`` is recomputed by the projection from the unchanged ``x``,
``lo``, ``v`` and ``mu`` instead of being kept between the residual sweep and the projection.

Equality with :mod:`.rattle`: bitwise on the CPU (tested, ``tests/test_rattle.py``). On CUDA both
kernels are built with Warp's default floating-point options (multiply-adds may be contracted to
FMA), where the compiler may contract differently in the two: equal to round-off, not promised
bitwise; ``scripts/bench_rattle.py --compare`` reports the largest difference it measures.
"""

import functools

import warp as wp

from ..core.arith import max_keep_nan
from ..core.layout import particle
from ..core.root_path import root_on_path
from .ftl import follow_func

#: capacities of the on-chip kernels (vertices); longer strands take the global-memory kernel
RATTLE_CAPACITIES = (8, 16, 24, 32)

#: longest strand (vertices) kept on chip
RATTLE_ON_CHIP_MAX = RATTLE_CAPACITIES[-1]

#: CUDA launch bounds (threads per block, blocks per SM) by (precision, capacity); not measured
#: yet (none: Warp's default block of 256 threads, unbounded registers)
RATTLE_LAUNCH_BOUNDS: dict = {}


def rattle_capacity(count: int) -> int | None:
    """Capacity of the on-chip kernel serving strands of ``count`` vertices (None: too long)."""
    for c in RATTLE_CAPACITIES:
        if count <= c:
            return c
    return None


@functools.cache
def rattle_fused_kernel(scalar, capacity: int):
    """The on-chip RATTLE kernel for ``scalar`` precision and strands of at most ``capacity``
    vertices (cached). Launch with ``dim`` = strands of the run; thread ``t`` advances device
    strand ``first_strand + t``. Same arguments as :func:`.rattle.rattle_kernel`'s otherwise,
    without the scratch arrays."""
    N = int(capacity)
    vec3 = wp.types.vector(3, scalar)
    rows = wp.types.matrix(shape=(N, 3), dtype=scalar)
    column = wp.types.vector(N, dtype=scalar)
    follow = follow_func(scalar)
    options = {"max_unroll": 4 * N + 16}
    last = N - 1

    @wp.kernel(enable_backward=False, module="unique", module_options=options,
               launch_bounds=RATTLE_LAUNCH_BOUNDS.get((scalar, N)))
    def rattle_on_chip(
        first_strand: wp.int32,
        strand_base: wp.array(dtype=wp.int32),
        strand_stride: wp.array(dtype=wp.int32),
        strand_count: wp.array(dtype=wp.int32),
        root_start: wp.array(dtype=vec3),
        root_end: wp.array(dtype=vec3),
        root_deviation_start: wp.array(dtype=vec3),
        root_deviation_end: wp.array(dtype=vec3),
        alpha_first: scalar,
        alpha_step: scalar,
        substeps: wp.int32,
        rest_lengths: wp.array(dtype=scalar),
        gravity: vec3,
        dt: scalar,
        iterations: wp.int32,
        fallback: scalar,
        accept: scalar,
        depth: wp.int32,
        positions: wp.array(dtype=vec3),
        velocities: wp.array(dtype=vec3),
        residual: wp.array(dtype=scalar),
        fallbacks: wp.array(dtype=wp.int32),
    ):
        s = first_strand + wp.tid()
        base = strand_base[s]
        stride = strand_stride[s]
        n = strand_count[s]
        m = n - 1
        r0 = root_start[s]
        r1 = root_end[s]
        d0 = root_deviation_start[s]
        d1 = root_deviation_end[s]
        k0 = particle(base, stride, 0)
        units = wp.int32(1) << depth
        zero = scalar(0.0)
        one = scalar(1.0)
        two = scalar(2.0)
        worst = residual[s]
        dropped = fallbacks[s]
        if n < 2:
            if n == 1:
                root = root_on_path(r0, r1 - r0, d0, d1, alpha_first + scalar(substeps - 1) * alpha_step)
                velocities[k0] = (root - positions[k0]) / (dt * scalar(substeps))
                positions[k0] = root
            return
        x = rows()
        lo = rows()
        v = rows()
        mu = column()
        cp = column()
        dp = column()
        rest = column()
        for i in range(wp.static(N)):
            if i < n:
                k = particle(base, stride, i)
                x[i] = positions[k]
                v[i] = velocities[k]
                rest[i] = rest_lengths[k]
        for step in range(substeps):
            alpha = alpha_first + scalar(step) * alpha_step
            target = root_on_path(r0, r1 - r0, d0, d1, alpha)
            begin = x[0] + lo[0]
            done = wp.int32(0)
            size = units
            while done < units:
                size = wp.min(size, units - done)
                h = dt * (scalar(size) / scalar(units))
                inv_h = scalar(1.0) / h
                half_h_g = gravity * (scalar(0.5) * h)
                root = target
                if done + size < units:
                    root = begin + (scalar(done + size) / scalar(units)) * (target - begin)
                # -- 1. kick-drift (the prediction q_i = h (v_i + h/2 g) is recomputed where read) --
                q0 = root - x[0]
                for i in range(wp.static(N)):
                    mu[i] = zero

                # -- 2. position constraints: Newton iterations, Thomas each --------------------------
                for it in range(iterations):
                    c_prev = zero
                    d_prev = zero
                    q_m = q0
                    r_m = vec3()
                    mu_m = zero
                    for j in range(1, wp.static(N)):
                        if j < n:
                            jp = wp.min(j + 1, wp.static(last))
                            r_j = (x[j] - x[j - 1]) + (lo[j] - lo[j - 1])
                            mu_j = mu[j]
                            q_j = h * (v[j] + half_h_g)
                            d = q_j - q_m
                            w = two
                            if j == 1:
                                w = one
                            d = d + (w * mu_j) * r_j - mu_m * r_m
                            r_p = vec3()
                            if j < m:
                                r_p = (x[jp] - x[j]) + (lo[jp] - lo[j])
                                d = d - mu[jp] * r_p
                            d = d + r_j
                            sub = -wp.dot(d, r_m)
                            sup = -wp.dot(d, r_p)
                            diag = w * wp.dot(d, r_j)
                            l = rest[j]
                            f = scalar(0.5) * (wp.dot(d, d) - l * l)
                            denom = diag - sub * c_prev
                            c_prev = sup / denom
                            d_prev = (-f - sub * d_prev) / denom
                            cp[j] = c_prev
                            dp[j] = d_prev
                            q_m = q_j
                            r_m = r_j
                            mu_m = mu_j
                    delta = zero
                    for jj in range(wp.static(last)):
                        j = wp.static(last) - jj
                        if j <= m:
                            delta = dp[j] - cp[j] * delta
                            mu[j] = mu[j] + delta

                # -- 3. the candidate's residual (the candidate is recomputed by the projection) -----
                res = zero
                prev = q0
                for i in range(1, wp.static(N)):
                    if i < n:
                        ip = wp.min(i + 1, wp.static(last))
                        r_i = (x[i] - x[i - 1]) + (lo[i] - lo[i - 1])
                        di = h * (v[i] + half_h_g) + mu[i] * r_i
                        if i < m:
                            di = di - mu[ip] * ((x[ip] - x[i]) + (lo[ip] - lo[i]))
                        l = rest[i]
                        dd = (di - prev) + r_i
                        res = max_keep_nan(res, wp.abs(wp.dot(dd, dd) / (l * l) - one))
                        prev = di
                if (not (res <= accept)) and size > 1:
                    size = size // 2
                    continue
                plain = wp.int32(0)
                if not (res <= fallback):
                    dropped = dropped + 1
                    plain = wp.int32(1)
                else:
                    worst = wp.max(worst, res)
                # follow-the-leader projection, the half kick; x + moved kept as hi + lo (TwoSum)
                moved = q0
                v[0] = moved * inv_h
                hi_m = x[0]
                lo_m = lo[0]
                x[0] = root
                lo[0] = vec3()
                origin = vec3()
                for i in range(1, wp.static(N)):
                    if i < n:
                        ip = wp.min(i + 1, wp.static(last))
                        hi_i = x[i]
                        lo_i = lo[i]
                        r_i = (hi_i - hi_m) + (lo_i - lo_m)
                        qi = h * (v[i] + half_h_g)
                        if plain == 0:
                            qi = qi + mu[i] * r_i
                            if i < m:
                                qi = qi - mu[ip] * ((x[ip] - hi_i) + (lo[ip] - lo_i))
                        seg = follow(origin, (qi - moved) + r_i, rest[i], origin, r_i)
                        moved = moved + (seg - r_i)
                        v[i] = moved * inv_h + half_h_g
                        b = moved + lo_i
                        t = hi_i + b
                        bb = t - hi_i
                        x[i] = t
                        lo[i] = (hi_i - (t - bb)) + (b - bb)
                        hi_m = hi_i
                        lo_m = lo_i

                # -- 4. velocity constraints (SPD tridiagonal, Thomas) --------------------------------
                c_prev = zero
                d_prev = zero
                r_m = vec3()
                for j in range(1, wp.static(N)):
                    if j < n:
                        jp = wp.min(j + 1, wp.static(last))
                        r_j = (x[j] - x[j - 1]) + (lo[j] - lo[j - 1])
                        diag = two * wp.dot(r_j, r_j)
                        if j == 1:
                            diag = wp.dot(r_j, r_j)
                        sub = -wp.dot(r_j, r_m)
                        sup = zero
                        if j < m:
                            sup = -wp.dot(r_j, (x[jp] - x[j]) + (lo[jp] - lo[j]))
                        rhs = -wp.dot(r_j, v[j] - v[j - 1])
                        denom = diag - sub * c_prev
                        c_prev = sup / denom
                        d_prev = (rhs - sub * d_prev) / denom
                        cp[j] = c_prev
                        dp[j] = d_prev
                        r_m = r_j
                nu = zero
                for jj in range(wp.static(last)):
                    j = wp.static(last) - jj
                    if j <= m:
                        nu = dp[j] - cp[j] * nu
                        mu[j] = nu
                for i in range(1, wp.static(N)):
                    if i < n:
                        ip = wp.min(i + 1, wp.static(last))
                        dv = mu[i] * ((x[i] - x[i - 1]) + (lo[i] - lo[i - 1]))
                        if i < m:
                            dv = dv - mu[ip] * ((x[ip] - x[i]) + (lo[ip] - lo[i]))
                        vi = v[i] + dv
                        if wp.isfinite(vi[0]) and wp.isfinite(vi[1]) and wp.isfinite(vi[2]):
                            v[i] = vi
                done = done + size
                size = size * 2
        for i in range(wp.static(N)):
            if i < n:
                k = particle(base, stride, i)
                positions[k] = x[i] + lo[i]
                velocities[k] = v[i]
        residual[s] = worst
        fallbacks[s] = dropped

    return rattle_on_chip
