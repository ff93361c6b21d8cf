"""Reference integrator of the inextensible chain: RATTLE, one thread per strand, float64 inside.

The equations of motion (the seed's, with unit masses and a kinematic root ``x_0(t)``)::

    x_i'' = g + lam_i grad_i c_i + lam_{i+1} grad_i c_{i+1},   c_i = (|x_i - x_{i-1}|^2 - l_i^2) / 2 = 0

are integrated with RATTLE (Andersen 1983), the constrained velocity Verlet: symplectic,
time-reversible, second order, constraints satisfied at every step. One step of ``dt`` (s):

1. predict ``q_i = x_i + dt v_i + dt^2/2 g`` and solve for ``mu`` (``mu = dt^2/2 lam``) so that
   ``x_i' = q_i + mu_i r_i - mu_{i+1} r_{i+1}`` (``r_j = x_j - x_{j-1}``, old segments) keeps every
   length: Newton's method on the tridiagonal system ``F_j(mu) = (|d_j|^2 - l_j^2)/2 = 0``
   (``d_j`` the new segments), each Newton system solved by the Thomas algorithm;
2. ``u_i = (x_i' - x_i)/dt + dt/2 g`` and ``v_i = u_i + nu_i r'_i - nu_{i+1} r'_{i+1}`` with ``nu``
   chosen so that every segment's stretching rate ``r'_j . (v_j - v_{j-1})`` is zero: one linear
   symmetric tridiagonal solve (Thomas).

Where Newton's method does not reach ``accept`` (a SHAKE-type position step has no solution
along the old segment directions once a segment turns too far in one step), the step is redone
as two halves, recursively (down to ``dt * 1e-6``); the piece length doubles again after each
success. Converged steps are untouched by this, so the scheme stays RATTLE wherever it can.
Where even the shortest piece has no solution (a step far beyond any stable one: dt of a second or
more for centimetre segments), the rest of the substep is one follow-the-leader projection of the
predictions (DFTL's :func:`~.ftl.follow_func`: exact lengths; a degenerate prediction keeps the old segment's direction), then the
velocity step 2, and the strand's residual becomes infinite: before, the failed Newton result
was taken and the strand went to NaN (dt = 1 s on the CPU) or to 1e152 m (dt = 1e6 s on CUDA).

The root is kinematic (infinite mass): it sits on its target on the frame's root path that
:class:`~dftl_warp.core.state.Control` describes (:func:`~dftl_warp.kernels.core.root_path.root_on_path`),
and its velocity is the target's finite difference ``(x_0' - x_0)/dt``: exact for a linear path,
the substep's mean on the C1 one (inside a substep, and its split pieces, the root moves along
the substep's chord: a difference of O(dt^2) from the path, which vanishes as the reference
converges).

Scratch memory, float64, in the model's particle layout (the same ``particle()`` indexing):
three vec3 arrays (current positions, velocities, predictions: 72 bytes per particle) and three
scalars (``mu``/``nu``, the Thomas sweep's modified super-diagonal and right-hand side: 24 bytes
per particle), 96 bytes per particle in all, plus one float64 per strand for the residual.
"""


import functools

import warp as wp

from ..core.arith import max_keep_nan
from ..core.layout import particle
from ..core.root_path import root_on_path
from .ftl import follow_func


@wp.func
def _to_d(v: wp.vec3f):
    return wp.vec3d(wp.float64(v[0]), wp.float64(v[1]), wp.float64(v[2]))


@wp.func
def _to_d(v: wp.vec3d):
    return v


@functools.cache
def rattle_kernel(scalar):
    """The RATTLE kernel for states stored in ``scalar`` precision (computation in float64)."""
    vec3 = wp.types.vector(3, scalar)
    f64 = wp.float64
    follow = follow_func(wp.float64)   # DFTL's projection: the fallback where no piece converges

    @wp.kernel(enable_backward=False, module="unique")
    def rattle_steps(
        strand_base: wp.array(dtype=wp.int32),
        strand_stride: wp.array(dtype=wp.int32),
        strand_count: wp.array(dtype=wp.int32),
        root_start: wp.array(dtype=vec3),
        root_end: wp.array(dtype=vec3),
        root_deviation_start: wp.array(dtype=vec3),
        root_deviation_end: wp.array(dtype=vec3),
        alpha_first: wp.float64,
        alpha_step: wp.float64,
        substeps: wp.int32,
        rest_lengths: wp.array(dtype=scalar),
        gravity: wp.vec3d,
        dt: wp.float64,
        tolerance: wp.float64,
        accept: wp.float64,
        max_iterations: wp.int32,
        positions_in: wp.array(dtype=vec3),
        velocities_in: wp.array(dtype=vec3),
        x: wp.array(dtype=wp.vec3d),
        v: wp.array(dtype=wp.vec3d),
        q: wp.array(dtype=wp.vec3d),
        mu: wp.array(dtype=wp.float64),
        cp: wp.array(dtype=wp.float64),
        dp: wp.array(dtype=wp.float64),
        residual: wp.array(dtype=wp.float64),
        positions_out: wp.array(dtype=vec3),
        velocities_out: wp.array(dtype=vec3),
    ):
        s = wp.tid()
        base = strand_base[s]
        stride = strand_stride[s]
        n = strand_count[s]
        m = n - 1  # constraints j = 1..m, constraint j stored at particle j's slot
        for i in range(n):
            k = particle(base, stride, i)
            x[k] = _to_d(positions_in[k])
            v[k] = _to_d(velocities_in[k])
        r0 = _to_d(root_start[s])
        r1 = _to_d(root_end[s])
        d0 = _to_d(root_deviation_start[s])
        d1 = _to_d(root_deviation_end[s])
        k0 = particle(base, stride, 0)
        worst = f64(0.0)
        for step in range(substeps):
            alpha = alpha_first + f64(step) * alpha_step
            target = root_on_path(r0, r1 - r0, d0, d1, alpha)
            begin = x[k0]
            elapsed = f64(0.0)
            h = dt
            while elapsed < dt:
                if elapsed + h >= dt:
                    h = dt - elapsed
                # the root moves along the substep's chord
                root = target
                if elapsed + h < dt:
                    root = begin + ((elapsed + h) / dt) * (target - begin)
                half_h_g = gravity * (f64(0.5) * h)
                q[k0] = root
                for i in range(1, n):
                    k = particle(base, stride, i)
                    q[k] = x[k] + h * (v[k] + half_h_g)
                    mu[k] = f64(0.0)

                # -- position constraints: Newton on F_j(mu) = (|d_j|^2 - l_j^2)/2 --------------
                res = f64(0.0)
                previous = f64(1.0e300)
                for it in range(max_iterations):
                    res = f64(0.0)
                    c_prev = f64(0.0)
                    d_prev = f64(0.0)
                    for j in range(1, n):
                        kj = particle(base, stride, j)
                        km = particle(base, stride, j - 1)
                        rj = x[kj] - x[km]
                        dj = q[kj] - q[km]
                        wsum = f64(2.0)
                        if j == 1:
                            wsum = f64(1.0)
                        dj = dj + (wsum * mu[kj]) * rj
                        rm = wp.vec3d()
                        rp = wp.vec3d()
                        if j > 1:
                            rm = x[km] - x[particle(base, stride, j - 2)]
                            dj = dj - mu[km] * rm
                        if j < m:
                            kp = particle(base, stride, j + 1)
                            rp = x[kp] - x[kj]
                            dj = dj - mu[kp] * rp
                        # Jacobian row: d F_j / d mu_{j-1}, mu_j, mu_{j+1} (zero outside the chain)
                        sub = -wp.dot(dj, rm)
                        sup = -wp.dot(dj, rp)
                        diag = wsum * wp.dot(dj, rj)
                        l2 = f64(rest_lengths[kj]) * f64(rest_lengths[kj])
                        f = f64(0.5) * (wp.dot(dj, dj) - l2)
                        res = max_keep_nan(res, wp.abs(f64(2.0) * f / l2))
                        # Thomas forward sweep on  sub*delta_{j-1} + diag*delta_j + sup*delta_{j+1} = -f
                        denom = diag - sub * c_prev
                        c_prev = sup / denom
                        d_prev = (-f - sub * d_prev) / denom
                        cp[kj] = c_prev
                        dp[kj] = d_prev
                    if res < tolerance or (it >= 2 and res > f64(0.5) * previous) or not wp.isfinite(res):
                        break
                    previous = res
                    # back substitution: mu_j += delta_j
                    delta = f64(0.0)
                    for jj in range(m):
                        j = m - jj
                        kj = particle(base, stride, j)
                        delta = dp[kj] - cp[kj] * delta
                        mu[kj] = mu[kj] + delta

                if (not (res < accept)) and h > dt * f64(1.0e-6):
                    # no solution reachable along the old segments at this step: halve it
                    h = f64(0.5) * h
                    continue
                if res < accept:
                    worst = max_keep_nan(worst, res)
                    # new positions x' = q + mu_i r_i - mu_{i+1} r_{i+1} (old segments), kept in q
                    for i in range(1, n):
                        k = particle(base, stride, i)
                        km = particle(base, stride, i - 1)
                        xi = q[k] + mu[k] * (x[k] - x[km])
                        if i < m:
                            kp = particle(base, stride, i + 1)
                            xi = xi - mu[kp] * (x[kp] - x[k])
                        q[k] = xi
                else:
                    # not even the shortest piece: the rest of the substep follows the leader
                    worst = f64(wp.inf)
                    h = dt - elapsed
                    root = target
                    half_h_g = gravity * (f64(0.5) * h)
                    q[k0] = root
                    for i in range(1, n):
                        k = particle(base, stride, i)
                        km = particle(base, stride, i - 1)
                        q[k] = follow(q[km], x[k] + h * (v[k] + half_h_g), f64(rest_lengths[k]), x[km], x[k])
                # half-step velocities plus the second half kick: u = (x' - x)/h + h/2 g
                inv_h = f64(1.0) / h
                v[k0] = (root - x[k0]) * inv_h
                x[k0] = root
                for i in range(1, n):
                    k = particle(base, stride, i)
                    v[k] = (q[k] - x[k]) * inv_h + half_h_g
                    x[k] = q[k]

                # -- velocity constraints: r'_j . (v_j - v_{j-1}) = 0, one symmetric tridiagonal solve
                c_prev = f64(0.0)
                d_prev = f64(0.0)
                for j in range(1, n):
                    kj = particle(base, stride, j)
                    km = particle(base, stride, j - 1)
                    rj = x[kj] - x[km]
                    diag = f64(2.0) * wp.dot(rj, rj)
                    sub = f64(0.0)
                    sup = f64(0.0)
                    if j == 1:
                        diag = wp.dot(rj, rj)
                    else:
                        sub = -wp.dot(rj, x[km] - x[particle(base, stride, j - 2)])
                    if j < m:
                        kp = particle(base, stride, j + 1)
                        sup = -wp.dot(rj, x[kp] - x[kj])
                    rhs = -wp.dot(rj, v[kj] - v[km])
                    denom = diag - sub * c_prev
                    c_prev = sup / denom
                    d_prev = (rhs - sub * d_prev) / denom
                    cp[kj] = c_prev
                    dp[kj] = d_prev
                nu_next = f64(0.0)
                for jj in range(m):
                    j = m - jj
                    kj = particle(base, stride, j)
                    nu_next = dp[kj] - cp[kj] * nu_next
                    mu[kj] = nu_next
                for i in range(1, n):
                    k = particle(base, stride, i)
                    km = particle(base, stride, i - 1)
                    dv = mu[k] * (x[k] - x[km])
                    if i < m:
                        kp = particle(base, stride, i + 1)
                        dv = dv - mu[kp] * (x[kp] - x[k])
                    v[k] = v[k] + dv
                elapsed = elapsed + h
                h = f64(2.0) * h  # try a longer piece again (capped at the substep's end)

        residual[s] = worst
        for i in range(n):
            k = particle(base, stride, i)
            xi = x[k]
            vi = v[k]
            positions_out[k] = vec3(scalar(xi[0]), scalar(xi[1]), scalar(xi[2]))
            velocities_out[k] = vec3(scalar(vi[0]), scalar(vi[1]), scalar(vi[2]))

    return rattle_steps
