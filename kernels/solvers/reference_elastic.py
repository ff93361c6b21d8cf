"""Reference integrator of inextensible *elastic* strands: RATTLE with the elastic solver's bending
energy, one thread per strand, float64 inside.

The reference kernel (:mod:`dftl_warp.kernels.solvers.reference`) integrates chains of equal unit
masses under gravity. This one adds the bending and twist energy of the ``elastic`` solver
(:mod:`dftl_warp.solvers.elastic_rest`, the same rest data)::

    E_b(x, F) = sum_j W_j/2 |(Dx)_j - F_j b_j|^2 + sum_j G_j (3 - tr(F_j^T F_{j-1} Q_j))

with the masses ``m_i`` of the elastic solver, the kinematic root and the kinematic clamp ghost
``x_{-1} = x_0 + (authored ghost - authored root)`` (it moves with the root's translation, as the
elastic solver's default clamp; so the root frame ``F_{-1}`` is the identity). The equations of
motion are those of the reduced energy ``E(x) = min_F E_b(x, F)``::

    m_i x_i'' = m_i g - dE/dx_i + (constraint forces),   dE/dx_i = d E_b / d x_i at F = F*(x)

(envelope theorem: at the minimiser the frames' own gradient vanishes, so only the explicit
dependence on x counts): ``-dE/dx_i = -(a_{i+1} rho_{i+1} - (a_i + c_i) rho_i + c_{i-1} rho_{i-1})``
with ``rho_j = W_j ((Dx)_j - F_j b_j)``, ``a_j = 1 / l_j``, ``c_j = 1 / l_{j+1}`` (``l_0`` the ghost
segment). The frames are solved to convergence after every accepted step (:func:`settle_frames`):
Newton's method on the rotation increments of all frames of a strand together (the Hessian is
block tridiagonal, 3x3 blocks, solved by the block Thomas algorithm), warm-started from the last
step's frames; where a Schur pivot is not positive definite (far from a minimum) one projective
Gauss-Seidel sweep root -> tip (each frame the polar factor of its local target) is taken instead.
Straight strands (``b = 0``) need no frames: the force does not depend on them.

RATTLE with masses (mass-weighted constraint corrections, ``w_i = 1 / m_i``, ``w_0 = 0``)::

    q_i = x_i + h v_i + h^2/2 a_i(x),          x'_i = q_i + w_i (mu_i r_i - mu_{i+1} r_{i+1})
    v'_i = (x'_i - x_i)/h + h/2 a_i(x') + w_i (nu_i r'_i - nu_{i+1} r'_{i+1})

``mu`` by Newton + Thomas on the squared-length residuals, ``nu`` by one symmetric tridiagonal
solve making every segment's stretching rate zero; steps whose position solve fails are halved as
in the reference kernel. Linear drag (``drag`` 1/s, toward still air) is split symmetrically
around the step (Strang): ``v *= exp(-drag h / 2)`` before the position prediction and before the
velocity projection, so the scheme stays second order.

Explicit forces: the step must resolve the stiffest bending mode, ``h omega_max < 2`` (velocity
Verlet's limit; the solver checks it, :mod:`dftl_warp.solvers.reference_elastic`).

Scratch (float64, the model's particle layout): positions, velocities, predictions,
accelerations, bending moments ``rho`` (5 vec3: 120 bytes), ``mu`` and the Thomas coefficients (3
scalars: 24), the frames (a quaternion, kept between calls as the warm start: 32), and for the
frames' Newton solve one 3x3 block and one vec3 (96): 272 bytes per particle; two float64 per
strand (the residuals).
"""

import functools

import warp as wp

from ..core.arith import max_keep_nan
from ..core.layout import particle
from ..core.root_path import root_on_path
from .reference import _to_d

F64 = wp.float64


@wp.func
def _axial(P: wp.mat33d):
    """s(P) with tr([t]x P) = -t . s(P)."""
    return wp.vec3d(P[2, 1] - P[1, 2], P[0, 2] - P[2, 0], P[1, 0] - P[0, 1])


@wp.func
def _curvature(xm: wp.vec3d, x: wp.vec3d, xp: wp.vec3d, lj: F64, lj1: F64):
    """(Dx)_j from x_{j-1}, x_j, x_{j+1} and the lengths l_j, l_{j+1} (the elastic solver's D)."""
    return -((F64(1.0) / lj) * (x - xm)) + (F64(1.0) / lj1) * (xp - x)


@wp.func
def _point(x: wp.array(dtype=wp.vec3d), base: wp.int32, stride: wp.int32, i: wp.int32, ghost: wp.vec3d):
    """x_i, with x_{-1} the clamp ghost."""
    if i < 0:
        return ghost
    return x[particle(base, stride, i)]


@wp.func
def _positive(S: wp.mat33d):
    """Leading principal minors of S all > 0 (S symmetric positive definite)."""
    m2 = S[0, 0] * S[1, 1] - S[0, 1] * S[1, 0]
    return S[0, 0] > F64(0.0) and m2 > F64(0.0) and wp.determinant(S) > F64(0.0)


@wp.func
def _closest_rotation(M: wp.mat33d):
    """The rotation maximising tr(R^T M) (polar factor of M; the reflection case turned)."""
    U = wp.mat33d()
    sig = wp.vec3d()
    V = wp.mat33d()
    wp.svd3(M, U, sig, V)
    R = U * wp.transpose(V)
    if wp.determinant(R) < F64(0.0):
        c = 0
        if sig[1] < sig[c]:
            c = 1
        if sig[2] < sig[c]:
            c = 2
        for r in range(3):
            U[r, c] = -U[r, c]
        R = U * wp.transpose(V)
    return wp.normalize(wp.quat_from_matrix(R))


@wp.func
def _sweep_frames(base: wp.int32, stride: wp.int32, n: wp.int32, x: wp.array(dtype=wp.vec3d), ghost: wp.vec3d,
                  length: wp.array(dtype=F64), bend: wp.array(dtype=F64), twist: wp.array(dtype=F64),
                  curvature: wp.array(dtype=wp.vec3d), rest_rotation: wp.array(dtype=wp.quatd),
                  frames: wp.array(dtype=wp.quatd)):
    """One Gauss-Seidel sweep root -> tip: each frame the exact minimiser given its neighbours."""
    N = n - 1
    Fprev = wp.identity(n=3, dtype=F64)
    for j in range(N):
        kj = particle(base, stride, j)
        kp = particle(base, stride, j + 1)
        dx = _curvature(_point(x, base, stride, j - 1, ghost), x[kj], x[kp], length[kj], length[kp])
        M = bend[kj] * wp.outer(dx, curvature[kj]) + twist[kj] * (Fprev * wp.quat_to_matrix(rest_rotation[kj]))
        if j + 1 < N:
            Fn = wp.quat_to_matrix(frames[kp])
            M = M + twist[kp] * (Fn * wp.transpose(wp.quat_to_matrix(rest_rotation[kp])))
        q = _closest_rotation(M)
        frames[kj] = q
        Fprev = wp.quat_to_matrix(q)


@wp.func
def settle_frames(base: wp.int32, stride: wp.int32, n: wp.int32, x: wp.array(dtype=wp.vec3d), ghost: wp.vec3d,
                  length: wp.array(dtype=F64), bend: wp.array(dtype=F64), twist: wp.array(dtype=F64),
                  curvature: wp.array(dtype=wp.vec3d), rest_rotation: wp.array(dtype=wp.quatd),
                  frames: wp.array(dtype=wp.quatd), block: wp.array(dtype=wp.mat33d),
                  rhs: wp.array(dtype=wp.vec3d), tolerance: F64, iterations: wp.int32):
    """Frames F*(x) minimising E_b at fixed x (Newton on the rotation increments ``t_j``,
    ``F_j <- exp([t_j]) F_j``, gradient and block-tridiagonal Hessian exact). Returns the last
    Newton step's largest rotation (rad): below ``tolerance`` the frames are converged (the next
    step would be of its square); 1e300 when no Newton step was taken."""
    N = n - 1
    eye = wp.identity(n=3, dtype=F64)
    last = F64(1.0e300)
    for _it in range(iterations):
        ok = int(1)
        Fprev = eye
        Cprev = wp.mat33d()
        dprev = wp.vec3d()
        for j in range(N):
            kj = particle(base, stride, j)
            kp = particle(base, stride, j + 1)
            a = _curvature(_point(x, base, stride, j - 1, ghost), x[kj], x[kp], length[kj], length[kp])
            Fj = wp.quat_to_matrix(frames[kj])
            c = Fj * curvature[kj]
            W = bend[kj]
            # bending: -W a . F_j b_j
            g = -W * wp.cross(c, a)
            D = -W * (F64(0.5) * (wp.outer(a, c) + wp.outer(c, a)) - wp.dot(a, c) * eye)
            # twist with the previous frame (the root frame for j = 0): G_j (3 - tr(F_j^T F_{j-1} Q_j))
            P = Fprev * wp.quat_to_matrix(rest_rotation[kj]) * wp.transpose(Fj)
            trP = P[0, 0] + P[1, 1] + P[2, 2]
            Gj = twist[kj]
            g = g - Gj * _axial(P)
            D = D + Gj * (trP * eye - F64(0.5) * (P + wp.transpose(P)))
            L = Gj * (P - trP * eye)                     # block (j, j-1)
            U = wp.mat33d()
            if j + 1 < N:
                Pn = Fj * wp.quat_to_matrix(rest_rotation[kp]) * wp.transpose(wp.quat_to_matrix(frames[kp]))
                trPn = Pn[0, 0] + Pn[1, 1] + Pn[2, 2]
                Gn = twist[kp]
                g = g + Gn * _axial(Pn)
                D = D + Gn * (trPn * eye - F64(0.5) * (Pn + wp.transpose(Pn)))
                U = Gn * (wp.transpose(Pn) - trPn * eye)  # block (j, j+1)
            S = D
            r = -g
            if j > 0:
                S = D - L * Cprev
                r = r - L * dprev
            if not _positive(S):
                ok = int(0)
                break
            Si = wp.inverse(S)
            Cprev = Si * U
            dprev = Si * r
            block[kj] = Cprev
            rhs[kj] = dprev
            Fprev = Fj
        if ok == 0:
            _sweep_frames(base, stride, n, x, ghost, length, bend, twist, curvature, rest_rotation, frames)
            last = F64(1.0e300)
            continue
        # back substitution tip -> root (the increments overwrite rhs), then the largest one
        t = wp.vec3d()
        biggest = F64(0.0)
        for jj in range(N):
            kj = particle(base, stride, N - 1 - jj)
            t = rhs[kj] - block[kj] * t
            rhs[kj] = t
            biggest = wp.max(biggest, wp.length(t))
        scale = F64(1.0)
        if biggest > F64(0.5):
            scale = F64(0.5) / biggest                   # damped far from the minimum
        for j in range(N):
            kj = particle(base, stride, j)
            t = scale * rhs[kj]
            th = wp.length(t)
            sh = F64(0.5)
            if th > F64(1.0e-30):
                sh = wp.sin(F64(0.5) * th) / th
            frames[kj] = wp.normalize(wp.quatd(sh * t[0], sh * t[1], sh * t[2], wp.cos(F64(0.5) * th)) * frames[kj])
        last = scale * biggest
        if last < tolerance:
            break
    return last


@wp.func
def accelerations(base: wp.int32, stride: wp.int32, n: wp.int32, x: wp.array(dtype=wp.vec3d), ghost: wp.vec3d,
                  length: wp.array(dtype=F64), inv_mass: wp.array(dtype=F64), bend: wp.array(dtype=F64),
                  curvature: wp.array(dtype=wp.vec3d), frames: wp.array(dtype=wp.quatd), curved: wp.int32,
                  gravity: wp.vec3d, rho: wp.array(dtype=wp.vec3d), acc: wp.array(dtype=wp.vec3d)):
    """acc_i = g - (1/m_i) dE_b/dx_i at the current frames, for the free particles."""
    N = n - 1
    for j in range(N):
        kj = particle(base, stride, j)
        kp = particle(base, stride, j + 1)
        dx = _curvature(_point(x, base, stride, j - 1, ghost), x[kj], x[kp], length[kj], length[kp])
        fb = curvature[kj]
        if curved != 0:
            fb = wp.quat_to_matrix(frames[kj]) * fb
        rho[kj] = bend[kj] * (dx - fb)
    for i in range(1, n):
        ki = particle(base, stride, i)
        inv_l = F64(1.0) / length[ki]
        f = -inv_l * rho[particle(base, stride, i - 1)]
        if i < N:
            kp = particle(base, stride, i + 1)
            inv_lp = F64(1.0) / length[kp]
            f = f + (inv_l + inv_lp) * rho[ki]
            if i + 1 < N:
                f = f - inv_lp * rho[kp]
        acc[ki] = gravity + inv_mass[ki] * f


@functools.cache
def rattle_elastic_kernel(scalar):
    """The elastic RATTLE kernel for states stored in ``scalar`` precision (float64 inside)."""
    vec3 = wp.types.vector(3, scalar)
    f64 = F64

    @wp.kernel(enable_backward=False, module="unique")
    def rattle_elastic_steps(
        # Model:
        strand_base: wp.array(dtype=wp.int32),
        strand_stride: wp.array(dtype=wp.int32),
        strand_count: wp.array(dtype=wp.int32),
        rest_lengths: wp.array(dtype=scalar),
        # Model, elastic (float64, the elastic solver's rest data; per particle slot, per device strand):
        length: wp.array(dtype=f64),
        inv_mass: wp.array(dtype=f64),
        bend: wp.array(dtype=f64),
        twist: wp.array(dtype=f64),
        curvature: wp.array(dtype=wp.vec3d),
        rest_rotation: wp.array(dtype=wp.quatd),
        ghost_offset: wp.array(dtype=wp.vec3d),
        curved: wp.array(dtype=wp.int32),
        # Control:
        root_start: wp.array(dtype=vec3),
        root_end: wp.array(dtype=vec3),
        root_deviation_start: wp.array(dtype=vec3),
        root_deviation_end: wp.array(dtype=vec3),
        alpha_first: f64,
        alpha_step: f64,
        substeps: wp.int32,
        # Settings:
        gravity: wp.vec3d,
        dt: f64,
        drag: f64,
        tolerance: f64,
        accept: f64,
        max_iterations: wp.int32,
        frame_tolerance: f64,
        frame_iterations: wp.int32,
        # Data in (the State):
        positions_in: wp.array(dtype=vec3),
        velocities_in: wp.array(dtype=vec3),
        # Scratch (frames persist between calls):
        x: wp.array(dtype=wp.vec3d),
        v: wp.array(dtype=wp.vec3d),
        q: wp.array(dtype=wp.vec3d),
        acc: wp.array(dtype=wp.vec3d),
        rho: wp.array(dtype=wp.vec3d),
        mu: wp.array(dtype=f64),
        cp: wp.array(dtype=f64),
        dp: wp.array(dtype=f64),
        frames: wp.array(dtype=wp.quatd),
        block: wp.array(dtype=wp.mat33d),
        block_rhs: wp.array(dtype=wp.vec3d),
        # Data out (residuals per strand, the State):
        residual: wp.array(dtype=f64),
        frame_residual: wp.array(dtype=f64),
        positions_out: wp.array(dtype=vec3),
        velocities_out: wp.array(dtype=vec3),
    ):
        s = wp.tid()
        base = strand_base[s]
        stride = strand_stride[s]
        n = strand_count[s]
        m = n - 1
        for i in range(n):
            k = particle(base, stride, i)
            x[k] = _to_d(positions_in[k])
            v[k] = _to_d(velocities_in[k])
        k0 = particle(base, stride, 0)
        worst = f64(0.0)
        worst_frames = f64(0.0)
        is_curved = curved[s]                 # 0 for strands of fewer than 2 particles
        offset = ghost_offset[s]
        if is_curved != 0:
            worst_frames = settle_frames(base, stride, n, x, x[k0] + offset, length, bend, twist, curvature,
                                         rest_rotation, frames, block, block_rhs, frame_tolerance, frame_iterations)
        accelerations(base, stride, n, x, x[k0] + offset, length, inv_mass, bend, curvature, frames, is_curved,
                      gravity, rho, acc)
        r0 = _to_d(root_start[s])
        r1 = _to_d(root_end[s])
        d0 = _to_d(root_deviation_start[s])
        d1 = _to_d(root_deviation_end[s])
        for step in range(substeps):
            alpha = alpha_first + f64(step) * alpha_step
            target = root_on_path(r0, r1 - r0, d0, d1, alpha)
            begin = x[k0]
            elapsed = f64(0.0)
            h = dt
            while elapsed < dt:
                if elapsed + h >= dt:
                    h = dt - elapsed
                root = target
                if elapsed + h < dt:
                    root = begin + ((elapsed + h) / dt) * (target - begin)
                damp = wp.exp(-f64(0.5) * drag * h)
                half_h = f64(0.5) * h
                q[k0] = root
                for i in range(1, n):
                    k = particle(base, stride, i)
                    q[k] = x[k] + h * (damp * v[k] + half_h * acc[k])
                    mu[k] = f64(0.0)

                # -- position constraints: Newton on F_j(mu) = (|d_j|^2 - l_j^2)/2, mass-weighted ----
                res = f64(0.0)
                previous = f64(1.0e300)
                for it in range(max_iterations):
                    res = f64(0.0)
                    c_prev = f64(0.0)
                    d_prev = f64(0.0)
                    for j in range(1, n):
                        kj = particle(base, stride, j)
                        km = particle(base, stride, j - 1)
                        wj = inv_mass[kj]
                        wm = f64(0.0)
                        if j > 1:
                            wm = inv_mass[km]
                        rj = x[kj] - x[km]
                        dj = q[kj] - q[km] + ((wj + wm) * mu[kj]) * rj
                        rm = wp.vec3d()
                        rp = wp.vec3d()
                        if j > 1:
                            rm = x[km] - x[particle(base, stride, j - 2)]
                            dj = dj - (wm * mu[km]) * rm
                        if j < m:
                            kp = particle(base, stride, j + 1)
                            rp = x[kp] - x[kj]
                            dj = dj - (wj * mu[kp]) * rp
                        sub = -wm * wp.dot(dj, rm)
                        sup = -wj * wp.dot(dj, rp)
                        diag = (wj + wm) * wp.dot(dj, rj)
                        l2 = f64(rest_lengths[kj]) * f64(rest_lengths[kj])
                        f = f64(0.5) * (wp.dot(dj, dj) - l2)
                        res = max_keep_nan(res, wp.abs(f64(2.0) * f / l2))
                        denom = diag - sub * c_prev
                        c_prev = sup / denom
                        d_prev = (-f - sub * d_prev) / denom
                        cp[kj] = c_prev
                        dp[kj] = d_prev
                    if res < tolerance or (it >= 2 and res > f64(0.5) * previous) or not wp.isfinite(res):
                        break
                    previous = res
                    delta = f64(0.0)
                    for jj in range(m):
                        j = m - jj
                        kj = particle(base, stride, j)
                        delta = dp[kj] - cp[kj] * delta
                        mu[kj] = mu[kj] + delta

                if (not (res < accept)) and h > dt * f64(1.0e-6):
                    h = f64(0.5) * h
                    continue
                worst = max_keep_nan(worst, res)

                # new positions x' = q + w_i (mu_i r_i - mu_{i+1} r_{i+1}) (old segments), kept in q
                for i in range(1, n):
                    k = particle(base, stride, i)
                    km = particle(base, stride, i - 1)
                    corr = mu[k] * (x[k] - x[km])
                    if i < m:
                        kp = particle(base, stride, i + 1)
                        corr = corr - mu[kp] * (x[kp] - x[k])
                    q[k] = q[k] + inv_mass[k] * corr
                inv_h = f64(1.0) / h
                v[k0] = (root - x[k0]) * inv_h
                x[k0] = root
                for i in range(1, n):
                    k = particle(base, stride, i)
                    v[k] = (q[k] - x[k]) * inv_h
                    x[k] = q[k]
                # forces at the new positions (frames at their minimiser), the second half kick and drag
                ghost = root + offset
                if is_curved != 0:
                    worst_frames = wp.max(worst_frames, settle_frames(
                        base, stride, n, x, ghost, length, bend, twist, curvature, rest_rotation, frames, block,
                        block_rhs, frame_tolerance, frame_iterations))
                accelerations(base, stride, n, x, ghost, length, inv_mass, bend, curvature, frames, is_curved,
                              gravity, rho, acc)
                for i in range(1, n):
                    k = particle(base, stride, i)
                    v[k] = damp * (v[k] + half_h * acc[k])

                # -- velocity constraints: r'_j . (v_j - v_{j-1}) = 0, mass-weighted, symmetric tridiagonal
                c_prev = f64(0.0)
                d_prev = f64(0.0)
                for j in range(1, n):
                    kj = particle(base, stride, j)
                    km = particle(base, stride, j - 1)
                    wj = inv_mass[kj]
                    wm = f64(0.0)
                    if j > 1:
                        wm = inv_mass[km]
                    rj = x[kj] - x[km]
                    diag = (wj + wm) * wp.dot(rj, rj)
                    sub = f64(0.0)
                    sup = f64(0.0)
                    if j > 1:
                        sub = -wm * wp.dot(rj, x[km] - x[particle(base, stride, j - 2)])
                    if j < m:
                        kp = particle(base, stride, j + 1)
                        sup = -wj * wp.dot(rj, x[kp] - x[kj])
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
                    v[k] = v[k] + inv_mass[k] * dv
                elapsed = elapsed + h
                h = f64(2.0) * h

        residual[s] = worst
        frame_residual[s] = worst_frames
        for i in range(n):
            k = particle(base, stride, i)
            xi = x[k]
            vi = v[k]
            positions_out[k] = vec3(scalar(xi[0]), scalar(xi[1]), scalar(xi[2]))
            velocities_out[k] = vec3(scalar(vi[0]), scalar(vi[1]), scalar(vi[2]))

    return rattle_elastic_steps
