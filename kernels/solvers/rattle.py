"""Production RATTLE kernel: the inextensible chain, second order, in the model's precision.

The scheme is the reference's (:mod:`.reference`): RATTLE (Andersen 1983), the constrained velocity
Verlet, with kinematic roots and unit masses. One step of ``h`` (s):

1. kick-drift: ``q_i = x_i + h v_i + h^2/2 g``; the root is put on its target (``alpha`` of the
   way along the frame's root path like DFTL's roots,
   :func:`~dftl_warp.kernels.core.root_path.root_on_path`);
2. position constraints: ``x'_i = q_i + mu_i r_i - mu_{i+1} r_{i+1}`` (``r_j = x_j - x_{j-1}``, old
   segments) with ``mu`` solving ``F_j(mu) = (|d_j|^2 - l_j^2)/2 = 0`` (``d_j`` the new segments) by a
   FIXED number of Newton iterations (``iterations``, no data-dependent loop), each Newton system
   (tridiagonal, ``J(x') M^-1 J(x)^T``) solved by the Thomas algorithm from ``mu = 0``;
3. exactness: a follow-the-leader projection of ``x'`` (root to tip, ``x'_i <- x'_{i-1} + l_i
   (x'_i - x'_{i-1}) / |x'_i - x'_{i-1}|``). Once Newton has converged this moves particles by
   round-off only (the kernel records the largest squared-length residual it removed); where it
   has not converged (the SHAKE position equations have no solution along the old segments: a
   segment turning by ~90 degrees in one step, a teleporting root) it is the fallback that keeps
   the chain inextensible. A Newton result that diverged (residual above ``fallback`` or not
   finite) is dropped and the plain prediction ``q`` is projected instead (counted per strand);
4. kick: ``v_i = (x'_i - x_i)/h + h/2 g``, then the velocity constraints
   ``r'_j . (v_j - v_{j-1}) = 0``: one symmetric positive definite tridiagonal solve (Thomas,
   ``J M^-1 J^T``, exact in one pass).

Steps 1, 2 and 4 are RATTLE: symplectic, time-reversible, second order, no numerical damping. The
root's velocity is ``(target - x_0)/h``: exact for a linear root path, the substep's mean on the
C1 path (the root moves along the substep's chord; pieces of a split substep along it too).

Cost per substep: ``2 * iterations + 5`` sweeps over the strand (DFTL: one). The substep loop runs
inside the kernel (one launch per frame); positions and velocities are updated in place in the
state arrays, the prediction and the multipliers live in scratch arrays in the model's particle
layout (slots only through :func:`~dftl_warp.kernels.core.layout.particle`): one vec3 and three
scalars per particle (24 bytes in float32), plus two values per strand of statistics.

Never NaN from finite input: the Thomas denominators of the velocity solve are those of a Gram
matrix of non-zero segments (positive); the Newton ones may vanish, which makes the residual non
finite and drops the Newton result (step 3); the projection handles degenerate segments as DFTL's
does (:func:`~dftl_warp.kernels.solvers.ftl.follow_func`).
"""

import functools

import warp as wp

from ..core.arith import max_keep_nan
from ..core.layout import particle
from ..core.root_path import root_on_path
from .ftl import follow_func


@functools.cache
def rattle_kernel(scalar):
    """The production RATTLE kernel for ``scalar`` precision (cached)."""
    vec3 = wp.types.vector(3, scalar)
    follow = follow_func(scalar)

    @wp.func
    def segment(x: wp.array(dtype=vec3), lo: wp.array(dtype=vec3), k: wp.int32, km: wp.int32):
        """Segment from slot ``km`` to slot ``k`` of positions held as ``x + lo``."""
        return (x[k] - x[km]) + (lo[k] - lo[km])

    @wp.kernel(enable_backward=False, module="unique")
    def rattle_steps(
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
        x: wp.array(dtype=vec3),
        v: wp.array(dtype=vec3),
        q: wp.array(dtype=vec3),
        lo: wp.array(dtype=vec3),
        mu: wp.array(dtype=scalar),
        cp: wp.array(dtype=scalar),
        dp: wp.array(dtype=scalar),
        residual: wp.array(dtype=scalar),
        fallbacks: wp.array(dtype=wp.int32),
    ):
        s = first_strand + wp.tid()
        base = strand_base[s]
        stride = strand_stride[s]
        n = strand_count[s]
        m = n - 1  # constraints j = 1..m, constraint j kept at particle j's slot
        r0 = root_start[s]
        r1 = root_end[s]
        d0 = root_deviation_start[s]
        d1 = root_deviation_end[s]
        k0 = particle(base, stride, 0)
        units = wp.int32(1) << depth  # a substep is split into pieces of whole units
        zero = scalar(0.0)
        one = scalar(1.0)
        two = scalar(2.0)
        worst = residual[s]
        dropped = fallbacks[s]
        if n < 2:
            # a lone root: kinematic, nothing to solve
            if n == 1:
                root = root_on_path(r0, r1 - r0, d0, d1, alpha_first + scalar(substeps - 1) * alpha_step)
                v[k0] = (root - x[k0]) / (dt * scalar(substeps))
                x[k0] = root
            return
        for i in range(n):
            lo[particle(base, stride, i)] = vec3()
        for step in range(substeps):
            alpha = alpha_first + scalar(step) * alpha_step
            target = root_on_path(r0, r1 - r0, d0, d1, alpha)
            begin = x[k0] + lo[k0]
            done = wp.int32(0)
            size = units
            while done < units:
                size = wp.min(size, units - done)
                h = dt * (scalar(size) / scalar(units))
                inv_h = scalar(1.0) / h
                half_h_g = gravity * (scalar(0.5) * h)
                # the root moves along the substep's chord
                root = target
                if done + size < units:
                    root = begin + (scalar(done + size) / scalar(units)) * (target - begin)
                # -- 1. kick-drift ---------------------------------------------------------------------
                q[k0] = root - x[k0]
                for i in range(1, n):
                    k = particle(base, stride, i)
                    q[k] = h * (v[k] + half_h_g)
                    mu[k] = zero

                # -- 2. position constraints: a fixed number of Newton iterations, Thomas each ---------
                for it in range(iterations):
                    c_prev = zero
                    d_prev = zero
                    x_m = x[k0]
                    q_m = q[k0]
                    x_j = x[particle(base, stride, 1)]
                    lo_m = lo[k0]
                    lo_j = lo[particle(base, stride, 1)]
                    r_m = vec3()  # r_{j-1}
                    mu_m = zero
                    for j in range(1, n):
                        kj = particle(base, stride, j)
                        r_j = (x_j - x_m) + (lo_j - lo_m)
                        mu_j = mu[kj]
                        d = q[kj] - q_m
                        w = two
                        if j == 1:
                            w = one
                        d = d + (w * mu_j) * r_j - mu_m * r_m
                        r_p = vec3()
                        x_p = x_j
                        lo_p = lo_j
                        if j < m:
                            kp = particle(base, stride, j + 1)
                            x_p = x[kp]
                            lo_p = lo[kp]
                            r_p = (x_p - x_j) + (lo_p - lo_j)
                            d = d - mu[kp] * r_p
                        d = d + r_j
                        sub = -wp.dot(d, r_m)
                        sup = -wp.dot(d, r_p)
                        diag = w * wp.dot(d, r_j)
                        l = rest_lengths[kj]
                        f = scalar(0.5) * (wp.dot(d, d) - l * l)
                        denom = diag - sub * c_prev
                        c_prev = sup / denom
                        d_prev = (-f - sub * d_prev) / denom
                        cp[kj] = c_prev
                        dp[kj] = d_prev
                        q_m = q[kj]
                        x_m = x_j
                        x_j = x_p
                        lo_m = lo_j
                        lo_j = lo_p
                        r_m = r_j
                        mu_m = mu_j
                    delta = zero
                    for jj in range(m):
                        j = m - jj
                        kj = particle(base, stride, j)
                        delta = dp[kj] - cp[kj] * delta
                        mu[kj] = mu[kj] + delta

                # -- 3. candidate x' = q + mu_i r_i - mu_{i+1} r_{i+1} (into q), its residual ----------
                res = zero
                prev = q[k0]
                for i in range(1, n):
                    k = particle(base, stride, i)
                    km = particle(base, stride, i - 1)
                    r_i = segment(x, lo, k, km)
                    di = q[k] + mu[k] * r_i
                    if i < m:
                        kp = particle(base, stride, i + 1)
                        di = di - mu[kp] * segment(x, lo, kp, k)
                    q[k] = di
                    l = rest_lengths[k]
                    dd = (di - prev) + r_i
                    res = max_keep_nan(res, wp.abs(wp.dot(dd, dd) / (l * l) - one))
                    prev = di
                if (not (res <= accept)) and size > 1:
                    # not converged in the fixed iterations: no solution along the old segments
                    # at this step, or too far from one; redo it as two halves
                    size = size // 2
                    continue
                if not (res <= fallback):
                    # diverged (or not finite) at the smallest piece: project the plain prediction
                    dropped = dropped + 1
                    for i in range(1, n):
                        k = particle(base, stride, i)
                        q[k] = h * (v[k] + half_h_g)
                else:
                    worst = wp.max(worst, res)
                # follow-the-leader projection of the segments (exact lengths), then the half kick.
                # Displacements, not positions, carry the step: the velocity (x' - x)/h is computed
                # from the displacement itself, free of the rounding of x' (in float32 that rounding,
                # ~1e-7 |x|, is a sizeable share of h^2 g at fine substeps and drifts the energy).
                moved = q[k0]
                v[k0] = moved * inv_h
                hi_m = x[k0]
                lo_m = lo[k0]
                x[k0] = root
                lo[k0] = vec3()
                origin = vec3()
                for i in range(1, n):
                    k = particle(base, stride, i)
                    hi_i = x[k]
                    lo_i = lo[k]
                    r_i = (hi_i - hi_m) + (lo_i - lo_m)  # the old segment
                    seg = follow(origin, (q[k] - moved) + r_i, rest_lengths[k], origin, r_i)
                    moved = moved + (seg - r_i)
                    v[k] = moved * inv_h + half_h_g
                    # x + moved as an unevaluated sum hi + lo (TwoSum): increments far below the
                    # rounding of x (h^2 g at fine substeps in float32) are not lost
                    b = moved + lo_i
                    t = hi_i + b
                    bb = t - hi_i
                    x[k] = t
                    lo[k] = (hi_i - (t - bb)) + (b - bb)
                    hi_m = hi_i
                    lo_m = lo_i

                # -- 4. velocity constraints: r'_j . (v_j - v_{j-1}) = 0 (SPD tridiagonal, Thomas) -----
                c_prev = zero
                d_prev = zero
                x_m = x[k0]
                v_m = v[k0]
                x_j = x[particle(base, stride, 1)]
                lo_m = lo[k0]
                lo_j = lo[particle(base, stride, 1)]
                r_m = vec3()
                for j in range(1, n):
                    kj = particle(base, stride, j)
                    r_j = (x_j - x_m) + (lo_j - lo_m)
                    diag = two * wp.dot(r_j, r_j)
                    if j == 1:
                        diag = wp.dot(r_j, r_j)
                    sub = -wp.dot(r_j, r_m)
                    sup = zero
                    x_p = x_j
                    lo_p = lo_j
                    if j < m:
                        kp = particle(base, stride, j + 1)
                        x_p = x[kp]
                        lo_p = lo[kp]
                        sup = -wp.dot(r_j, (x_p - x_j) + (lo_p - lo_j))
                    v_j = v[kj]
                    rhs = -wp.dot(r_j, v_j - v_m)
                    denom = diag - sub * c_prev
                    c_prev = sup / denom
                    d_prev = (rhs - sub * d_prev) / denom
                    cp[kj] = c_prev
                    dp[kj] = d_prev
                    x_m = x_j
                    x_j = x_p
                    lo_m = lo_j
                    lo_j = lo_p
                    v_m = v_j
                    r_m = r_j
                nu = zero
                for jj in range(m):
                    j = m - jj
                    kj = particle(base, stride, j)
                    nu = dp[kj] - cp[kj] * nu
                    mu[kj] = nu
                for i in range(1, n):
                    k = particle(base, stride, i)
                    km = particle(base, stride, i - 1)
                    dv = mu[k] * segment(x, lo, k, km)
                    if i < m:
                        kp = particle(base, stride, i + 1)
                        dv = dv - mu[kp] * segment(x, lo, kp, k)
                    vi = v[k] + dv
                    # a degenerate (zero-length) segment leaves the velocity unprojected, never NaN
                    if wp.isfinite(vi[0]) and wp.isfinite(vi[1]) and wp.isfinite(vi[2]):
                        v[k] = vi
                done = done + size
                size = size * 2  # try a longer piece again (capped at the substep's end)
        for i in range(n):
            k = particle(base, stride, i)
            x[k] = x[k] + lo[k]
        residual[s] = worst
        fallbacks[s] = dropped

    return rattle_steps
