"""Elastic-rod step kernel (scheme K): one thread per strand, three sweeps per step.

The solver and the formulation are described in :mod:`dftl_warp.solvers.elastic` and
:mod:`dftl_warp.solvers.elastic_rest`. One step of ``dt = h`` (s) of a strand of ``N + 1``
particles (root 0 kinematic, a kinematic clamp ghost ``x_{-1}`` behind it):

A. **frames, root -> tip** (curved strands only): one Gauss-Seidel sweep of the projective-dynamics
   local step, ``F_j = polar(W_j (Dx^n)_j b_j^T + G_j F_{j-1} Qb_j + G_{j+1} F_{j+1} Qb_{j+1}^T)``,
   ``F_{-1}`` the root frame (the minimal rotation from the authored clamp direction to the current
   one), polar factor by at most :data:`POLAR_ITERATIONS` Newton steps on the rotation from the
   last step's frame (exact at convergence), ``wp.svd3`` where they do not converge;
B. **elimination, tip -> root**: the block-pentadiagonal KKT system (4x4 blocks ``z_k = (v_k, mu_k)``)
   of the linearly implicit velocity solve with the exact linearised inextensibility constraint,
   ``[A J^T; J 0] [v; mu] = [M v^n + h f; J_0 v_0]``, ``A = M (1 + h drag) + h^2 K + h^2 K_T``, is
   factored as a reversed block ``L D L^T`` whose Schur complements are formed from the couplings,
   ``D_k = A_kk - B D^-1 B^T`` (stable; the multiplier form ``U D U^T``, ``U = B D^-1``, is not);
   the forces ``f`` (gravity + bending with the frames of A, the root and ghost at their step-end
   targets) are built on the way;
C. **back substitution, root -> tip**, fused with the follow-the-leader projection of
   ``p_k = x_k + h v_k`` (exact segment lengths), the colliders' response (as the featured DFTL
   sweep: collide, back to the rest length from the leader), the velocity ``(x^{n+1} - x^n)/h`` in DFTL's
   prior or posterior form, and the tensions ``T_k = -mu_k / h``.

Precision: ``scalar`` is the storage precision of the State, ``real`` the computation's (the model
arrays and the scratch are in ``real``). Module options as the DFTL step kernels (no FMA contraction).

Memory traffic per free particle per step: the model (14 scalars; +9 re-read by A on curved
strands), the State in and out (positions, velocities, tensions, frames, corrections in the prior
form) and the scratch (``D^-1`` 10 symmetric, ``B_{k-1,k}`` 12, ``w`` 4) written in B, read in C.

Counted per free particle per step (prior form, curved strand): storage 38 scalars, computation 73
(26 of them the scratch written, 26 read): 444 B in float32, against bare DFTL's 76 B
(docs/elastic.md "Cost"). Straight strands skip A; the posterior form carries no c.
"""

import functools

import warp as wp

from ..core.layout import particle
from ..core.root_path import root_on_path
from ..features.collide import collide_all_func, collider_flags
from ..features.grid import grid_sample_func
from ..features.step import NOISE_STRIDE, check_flags, feature_struct
from . import elastic_blocks
from .elastic_blocks import block_funcs

#: as the DFTL step kernels: no floating-point contraction
ELASTIC_MODULE_OPTIONS = {"fuse_fp": False}

#: Newton iterations of the frames' rotation extraction before it falls back to ``wp.svd3``
POLAR_ITERATIONS = 4

#: the feature flags the elastic step supports besides the registered collider shapes'
ELASTIC_OTHER_FLAGS = frozenset({"drag", "wind", "wind_noise", "hair_hair"})

#: CUDA register caps of the float32-arithmetic kernels, by the sweeps they run (the float64 ones are
#: uncapped). H200, 1M curly strands x 33, 8 substeps: the single kernel uncapped took 251 registers
#: (98.4 ms a frame), capped at 128 81.6 ms, at 96 110.3 ms (scripts/profile_elastic.py); the three
#: sweeps as separate kernels 6.4 ms a step against its 7.1 (scripts/probe_elastic_phases.py; B, the
#: elimination, takes the 128, A and C 64-72 uncapped; C with colliders spills at 64; docs/elastic.md)
CUDA_MAX_REGISTERS_F32 = {"ABC": 128, "A": 128, "B": 128, "C": 128}

#: the sweeps of one step, launched as one kernel each on CUDA devices (each holds only the registers
#: it needs, so more threads are in flight); one kernel on the CPU, where a strand's data stays in cache
CUDA_PHASES = ("A", "B", "C")


def elastic_step_kernels(scalar, real, correction: str, flags: frozenset, accelerations: bool, cuda: bool):
    """The kernels of one step, launched in order with the same arguments (:data:`CUDA_PHASES`)."""
    return tuple(elastic_kernel(scalar, real, correction, flags, accelerations, phases)
                 for phases in (CUDA_PHASES if cuda else ("ABC",)))


@wp.struct
class NoFeatures:
    """The feature struct of a model without features (the kernel's ``features`` argument)."""

    unused: wp.int32


def elastic_flags() -> frozenset:
    """Every feature flag the elastic step supports: the colliders', drag, wind and hair-hair."""
    return frozenset(collider_flags()) | ELASTIC_OTHER_FLAGS


def elastic_features_struct(scalar, flags: frozenset):
    """The struct type the elastic kernel for ``flags`` takes (the featured DFTL step's for the
    same flags, :func:`~dftl_warp.kernels.features.step.feature_struct`; :class:`NoFeatures`
    without flags)."""
    flags = check_flags(flags)
    return feature_struct(scalar, flags) if flags else NoFeatures


@functools.cache
def elastic_kernel(scalar, real, correction: str, flags: frozenset = frozenset(), accelerations: bool = False,
                   phases: str = "ABC"):
    """The scheme-K step kernel for States stored in ``scalar``, computing in ``real``, with the
    velocity correction in ``correction`` form (``"prior"`` or ``"posterior"``) and the features
    ``flags`` (:func:`elastic_flags`: colliders after the follow-the-leader projection; drag, wind
    and hair-hair friction in the implicit solve, hair-hair repulsion as an explicit force).

    ``accelerations``: drag, wind and hair-hair come from the velocity pass before the step
    (``kernels/features/air_grid.py``, its ``"acceleration"`` form) through the ``accelerations``
    argument, ``(a, c)`` per particle, and ``flags`` holds the colliders only.

    ``phases``: the sweeps the kernel runs ("ABC", or one of "A", "B", "C": launched in that order with
    the same arguments they compute the same values, :func:`elastic_step_kernels`)."""
    flags = check_flags(flags)
    extra = flags - elastic_flags()
    if extra:
        raise ValueError(f"the elastic step does not support the feature flags {sorted(extra)}")
    if accelerations and flags & ELASTIC_OTHER_FLAGS:
        raise ValueError("with the velocity pass's accelerations the step takes the collider flags only")
    PASSED = bool(accelerations)
    PHASE_A, PHASE_B, PHASE_C = ("A" in phases), ("B" in phases), ("C" in phases)
    Features = elastic_features_struct(scalar, flags)
    COLLIDE = bool(flags & set(collider_flags()))
    collide_all = collide_all_func(scalar, Features, flags) if COLLIDE else None
    DRAG = "drag" in flags
    WIND = "wind" in flags
    WIND_NOISE = "wind_noise" in flags
    HAIR_HAIR = "hair_hair" in flags
    grid_sample = grid_sample_func(scalar) if HAIR_HAIR else None
    vec3s = wp.types.vector(3, scalar)
    quats = wp.types.quaternion(scalar)
    mat33s = wp.types.matrix((3, 3), scalar)
    vec3 = wp.types.vector(3, real)
    vec4 = wp.types.vector(4, real)
    mat33 = wp.types.matrix((3, 3), real)
    mat44 = wp.types.matrix((4, 4), real)
    mat34 = wp.types.matrix((3, 4), real)
    vec6 = wp.types.vector(6, real)
    vec10 = wp.types.vector(10, real)
    quat = wp.types.quaternion(real)
    prior = correction == "prior"

    @wp.func
    def ld(v: vec3s):
        return vec3(real(v[0]), real(v[1]), real(v[2]))

    @wp.func
    def st(v: vec3):
        return vec3s(scalar(v[0]), scalar(v[1]), scalar(v[2]))

    @wp.func
    def ldq(q: quats):
        return wp.normalize(quat(real(q[0]), real(q[1]), real(q[2]), real(q[3])))

    @wp.func
    def ldm(m: mat33s):
        return mat33(real(m[0, 0]), real(m[0, 1]), real(m[0, 2]), real(m[1, 0]), real(m[1, 1]), real(m[1, 2]),
                     real(m[2, 0]), real(m[2, 1]), real(m[2, 2]))

    @wp.func
    def clamp_turn(start: mat33s, end: mat33s, alpha: real):
        """The clamp's rotation from its authored pose, between the frame's start and end rotations
        (normalised linear interpolation of their quaternions, the shorter way)."""
        qa = wp.quat_from_matrix(ldm(start))
        qb = wp.quat_from_matrix(ldm(end))
        if qa[0] * qb[0] + qa[1] * qb[1] + qa[2] * qb[2] + qa[3] * qb[3] < real(0.0):
            qb = quat(-qb[0], -qb[1], -qb[2], -qb[3])
        return wp.quat_to_matrix(wp.normalize(qa + alpha * (qb - qa)))

    @wp.func
    def stq(q: quat):
        return quats(scalar(q[0]), scalar(q[1]), scalar(q[2]), scalar(q[3]))

    # the frame's rotation: Newton on the rotation manifold from the last step's frame, svd3 where
    # it does not converge in POLAR_ITERATIONS (see :func:`polar_rotation`)
    tol = real(1.0e-8) if real == wp.float64 else real(1.0e-4)

    @wp.func
    def polar_rotation(M: mat33, q0: quat):
        """The rotation maximising tr(F^T M) (the polar factor of M), from the warm start q0."""
        q = q0
        for _it in range(POLAR_ITERATIONS):
            R = wp.quat_to_matrix(q)
            S = wp.transpose(R) * M
            g = vec3(S[2, 1] - S[1, 2], S[0, 2] - S[2, 0], S[1, 0] - S[0, 1])
            tr = S[0, 0] + S[1, 1] + S[2, 2]
            H = mat33(tr - S[0, 0], real(-0.5) * (S[0, 1] + S[1, 0]), real(-0.5) * (S[0, 2] + S[2, 0]),
                      real(-0.5) * (S[0, 1] + S[1, 0]), tr - S[1, 1], real(-0.5) * (S[1, 2] + S[2, 1]),
                      real(-0.5) * (S[0, 2] + S[2, 0]), real(-0.5) * (S[1, 2] + S[2, 1]), tr - S[2, 2])
            # H must be positive definite (near the maximum): leading minors
            m1 = H[0, 0]
            m2 = H[0, 0] * H[1, 1] - H[0, 1] * H[1, 0]
            m3 = wp.determinant(H)
            if m1 <= real(0.0) or m2 <= real(0.0) or m3 <= real(0.0):
                break
            w = wp.inverse(H) * g
            th = wp.length(w)
            if th > real(0.5):
                break
            sh = real(0.5)
            if th > real(1.0e-30):
                sh = wp.sin(real(0.5) * th) / th
            q = wp.normalize(q * quat(sh * w[0], sh * w[1], sh * w[2], wp.cos(real(0.5) * th)))
            if th < tol:
                return q
        U = mat33()
        sig = vec3()
        V = mat33()
        wp.svd3(M, U, sig, V)
        return wp.quat_from_matrix(U * wp.transpose(V))

    blocks = block_funcs(real)
    between = blocks.between
    curv = blocks.curv
    upper3_packed = blocks.upper3_packed
    unpack_symmetric = blocks.unpack_symmetric
    block1 = blocks.block1
    kkt_inverse = blocks.kkt_plane if elastic_blocks.KKT_INVERSE == "plane" else blocks.kkt_generic

    @wp.kernel(enable_backward=False, module="unique", module_options=ELASTIC_MODULE_OPTIONS,
               cuda_max_registers=CUDA_MAX_REGISTERS_F32[phases] if real == wp.float32 else None)
    def elastic_step(
        # Model:
        strand_base: wp.array(dtype=wp.int32),
        strand_stride: wp.array(dtype=wp.int32),
        strand_count: wp.array(dtype=wp.int32),
        length: wp.array(dtype=real),
        mass: wp.array(dtype=real),
        bend: wp.array(dtype=real),
        twist: wp.array(dtype=real),
        k0: wp.array(dtype=real),
        k1: wp.array(dtype=real),
        k2: wp.array(dtype=real),
        curvature: wp.array(dtype=vec3),
        rest_rotation: wp.array(dtype=quat),
        clamp_direction: wp.array(dtype=vec3),
        curved: wp.array(dtype=wp.int32),
        # Control (per device strand): roots and their path's deviations, clamp ghosts (offsets from
        # the root when relative) and theirs (root_on_path; unused when relative), the clamps'
        # rotations from their authored poses at the frame's start and end (the twist they drive)
        root_start: wp.array(dtype=vec3s),
        root_end: wp.array(dtype=vec3s),
        root_deviation_start: wp.array(dtype=vec3s),
        root_deviation_end: wp.array(dtype=vec3s),
        clamp_start: wp.array(dtype=vec3s),
        clamp_end: wp.array(dtype=vec3s),
        clamp_deviation_start: wp.array(dtype=vec3s),
        clamp_deviation_end: wp.array(dtype=vec3s),
        clamp_rotation_start: wp.array(dtype=mat33s),
        clamp_rotation_end: wp.array(dtype=mat33s),
        clamp_relative: wp.int32,
        root_alpha: real,
        gravity: vec3,
        dt: real,
        damping: real,
        drag: real,
        features: Features,
        # State in:
        positions_in: wp.array(dtype=vec3s),
        velocities_in: wp.array(dtype=vec3s),
        corrections_in: wp.array(dtype=vec3s),
        tensions_in: wp.array(dtype=scalar),
        frames_in: wp.array(dtype=quats),
        clamps_in: wp.array(dtype=vec3s),
        # Scratch (per particle, written in B, read in C):
        factor_inv: wp.array(dtype=vec10),
        factor_up: wp.array(dtype=mat34),
        factor_rhs: wp.array(dtype=vec4),
        # Data in (the velocity pass, when PASSED): (a, c) per particle, m/s^2 and 1/s
        accelerations: wp.array(dtype=vec4),
        # State out:
        positions_out: wp.array(dtype=vec3s),
        velocities_out: wp.array(dtype=vec3s),
        corrections_out: wp.array(dtype=vec3s),
        tensions_out: wp.array(dtype=scalar),
        frames_out: wp.array(dtype=quats),
        clamps_out: wp.array(dtype=vec3s),
    ):
        s = wp.tid()
        base = strand_base[s]
        stride = strand_stride[s]
        n = strand_count[s]
        h = dt
        h2 = h * h
        zero3 = vec3()
        k0s = particle(base, stride, 0)
        root_old = ld(positions_in[k0s])
        ra = ld(root_start[s])
        root_new = root_on_path(ra, ld(root_end[s]) - ra, ld(root_deviation_start[s]), ld(root_deviation_end[s]),
                                root_alpha)
        ghost_old = ld(clamps_in[s])
        ca = ld(clamp_start[s])
        ghost_new = root_new + ca
        if clamp_relative == 0:
            ghost_new = root_on_path(ca, ld(clamp_end[s]) - ca, ld(clamp_deviation_start[s]),
                                     ld(clamp_deviation_end[s]), root_alpha)
        v0 = (root_new - root_old) / h
        if wp.static(PHASE_C):
            positions_out[k0s] = st(root_new)
            velocities_out[k0s] = st(v0)
            tensions_out[k0s] = scalar(0.0)
            clamps_out[s] = st(ghost_new)
            if wp.static(prior):
                corrections_out[k0s] = vec3s()
        if n < 2:
            return
        N = n - 1
        is_curved = curved[s] != 0
        # drag (1/s): the solver's own plus the Drag feature's, toward the air velocity (wind)
        drag_s = drag
        air = zero3
        if wp.static(DRAG):
            drag_s = drag + real(features.drag[s])
            if wp.static(WIND):
                wa = ld(features.wind_velocity[0])
                air = wa + root_alpha * (ld(features.wind_velocity[1]) - wa)
            if wp.static(WIND_NOISE):
                t0 = features.wind_time[0]
                time = t0 + scalar(root_alpha) * (features.wind_time[1] - t0)
                noise_state = wp.uint32(features.noise_seed)
                gust = zero3
                noise_at = int(-1)
        if wp.static(HAIR_HAIR):
            # hair-hair (Petrovic et al. 2005): friction toward the grid velocity at rate c (1/s),
            # implicit as drag; repulsion down the density gradient, an explicit acceleration (m/s^2)
            hh_friction = real(features.grid_friction)
            hh_push = real(features.grid_repulsion * features.grid_h)

        # ---- A: frames, Gauss-Seidel root -> tip, at x^n (ghost at its old place) ----------------
        if wp.static(PHASE_A):
            if is_curved:
                # the root frame: the clamp's rotation (its twist about the first segment included), then
                # the minimal rotation onto the ghost's actual direction (on the path, mid-frame)
                R = clamp_turn(clamp_rotation_start[s], clamp_rotation_end[s], root_alpha)
                Fprev = between(R * clamp_direction[s], root_new - ghost_new) * R
                xm = ghost_old
                xj = root_old
                for j in range(N):
                    kj = particle(base, stride, j)
                    kp = particle(base, stride, j + 1)
                    xp = ld(positions_in[kp])
                    dx = curv(xm, xj, xp, length[kj], length[kp])
                    M = bend[kj] * wp.outer(dx, curvature[kj]) + twist[kj] * (Fprev * wp.quat_to_matrix(rest_rotation[kj]))
                    if j + 1 < N:
                        Fn = wp.quat_to_matrix(ldq(frames_in[kp]))
                        M = M + twist[kp] * (Fn * wp.transpose(wp.quat_to_matrix(rest_rotation[kp])))
                    qF = polar_rotation(M, ldq(frames_in[kj]))
                    frames_out[kj] = stq(qF)
                    Fprev = wp.quat_to_matrix(qF)
                    xm = xj
                    xj = xp
            else:
                for j in range(N):
                    kj = particle(base, stride, j)
                    frames_out[kj] = frames_in[kj]

        # ---- B: forces and elimination, tip -> root -----------------------------------------------
        if wp.static(PHASE_B):
            # carried from the two particles eliminated last (35 words): D_{k+1}^-1 packed symmetric (10),
            # the velocity part of D_{k+2}^-1 (symmetric: 6), the coupling B_{k,k+1} (fill included; its
            # last row is zero: 12, as stored), u_{k+1} (4) and the velocity part of u_{k+2} (3), where
            # u = D^-1 w (so B D^-1 w = B u); 56 words before (D^-1 k+1, k+2 and B_{k,k+1} 4x4, w k+1, k+2)
            Di1p = vec10()
            Di2u = vec6()
            Bk1 = mat34()
            u1 = vec4()
            u2 = zero3
            rho_hi = zero3
            rho_mid = zero3
            kt_hi = real(0.0)
            c_hi = vec3s()
            kk = particle(base, stride, N)
            xk = ld(positions_in[kk])
            xk1 = ld(positions_in[particle(base, stride, N - 1)])
            if N == 1:
                xk1 = root_new
            for step in range(N):
                k = N - step
                kk = particle(base, stride, k)
                km = particle(base, stride, k - 1)
                lk = length[kk]
                # x_{k-1} for the curvature (root at its target) and x_{k-2} (root / ghost at targets)
                xk2 = ghost_new
                if k - 2 == 0:
                    xk2 = root_new
                elif k - 2 > 0:
                    xk2 = ld(positions_in[particle(base, stride, k - 2)])
                x_lead = xk1
                if k - 1 == 0:
                    x_lead = root_old
                e = (xk - x_lead) / lk
                # rho_{k-1} = W (Dx - F b)
                fb_ = curvature[km]
                if is_curved:
                    fb_ = wp.quat_to_matrix(ldq(frames_out[km])) * curvature[km]
                rho_lo = bend[km] * (curv(xk2, xk1, xk, length[km], lk) - fb_)
                ga_lo = real(1.0) / lk
                al_k = real(0.0)
                ga_k = real(0.0)
                al_hi = real(0.0)
                if k < N:
                    kn = particle(base, stride, k + 1)
                    al_k = real(1.0) / lk
                    ga_k = real(1.0) / length[kn]
                    if k + 1 < N:
                        al_hi = real(1.0) / length[kn]
                fb = -(ga_lo * rho_lo - (al_k + ga_k) * rho_mid + al_hi * rho_hi)
                kt_k = wp.max(real(tensions_in[kk]), real(0.0)) / lk
                mk = mass[kk]
                f = mk * gravity + fb
                if k == 1:
                    f = f + (kt_k * v0) * h
                vk = ld(velocities_in[kk])
                rv = mk * vk + h * f
                if wp.static(prior):
                    xp_ = xk - damping * ld(c_hi)
                    rv = mk * (vk + (xp_ - xk) / h) + h * f
                if wp.static(DRAG):
                    w_air = air
                    if wp.static(WIND_NOISE):
                        # curl noise sampled every NOISE_STRIDE particles, held in between (as DFTL)
                        si = 1 + ((k - 1) // NOISE_STRIDE) * NOISE_STRIDE
                        if si != noise_at:
                            xs_ = positions_in[particle(base, stride, si)]
                            xyzt = wp.vec4f(wp.float32(xs_[0] * features.noise_inv_scale),
                                            wp.float32(xs_[1] * features.noise_inv_scale),
                                            wp.float32(xs_[2] * features.noise_inv_scale),
                                            wp.float32(time * features.noise_frequency))
                            gust = real(features.noise_amplitude) * vec3(wp.curlnoise(noise_state, xyzt))
                            noise_at = si
                        w_air = air + gust
                    rv = rv + (h * mk * drag_s) * w_air
                a_drag = drag_s
                if wp.static(PASSED):
                    ac = accelerations[kk]
                    rv = rv + (h * mk) * vec3(ac[0], ac[1], ac[2])
                    a_drag = ac[3]
                if wp.static(HAIR_HAIR):
                    v_grid, grad = grid_sample(positions_in[kk], features.grid_weights[kk], features.grid_threshold,
                                               features.grid_lower,
                                               features.grid_inv_h, features.grid_nx, features.grid_ny, features.grid_nz,
                                               features.grid_density, features.grid_mass,
                                               features.grid_momentum)
                    rv = rv + (h * mk) * (hh_friction * ld(v_grid) - hh_push * ld(grad))
                    a_drag = a_drag + hh_friction
                rk = vec4(rv[0], rv[1], rv[2], real(0.0))
                if k == 1:
                    rk[3] = wp.dot(e, v0)
                a0 = mk * (real(1.0) + h * a_drag) + h2 * k0[kk] + h2 * (kt_k + kt_hi)
                # Schur complements from the couplings themselves, B D^-1 B^T (B_{k,k+2} = a2 P): never
                # through the multipliers U = B D^-1 as U D U^T, whose round trip through D amplified
                # round-off by about D's condition at every particle (a 47-point curl's solve was wrong
                # by 200% at 8 substeps per frame, and the strand rang; docs/elastic.md "Stability")
                # B_{k,k+1} has a zero last row and B_{k,k+2} = a2 P: both updates touch only D_k's velocity
                # part G (3x3); w_k = r_k - B_{k,k+1} u_{k+1} - a2 P u_{k+2}, u = D^-1 w (carried)
                a2k = h2 * k2[kk]
                BD = Bk1 * unpack_symmetric(Di1p)
                Bu = Bk1 * u1
                wk = rk - vec4(Bu[0], Bu[1], Bu[2], real(0.0)) - a2k * vec4(u2[0], u2[1], u2[2], real(0.0))
                B1 = mat34()
                if k >= 2:
                    # B_{k-1,k} = A_{k-1,k} - B_{k-1,k+1} D_{k+1}^-1 B_{k,k+1}^T, B_{k-1,k+1} = a2 P
                    B1 = block1(h2 * k1[km] - h2 * kt_k, e, h2 * k2[km], BD)
                # D_k^-1, packed symmetric, from its velocity block a0 I - B D^-1 B^T - a2^2 (D_{k+2}^-1)_vv
                # and its constraint row e (kernels/solvers/elastic_blocks.py, KKT_INVERSE)
                Di_packed = kkt_inverse(a0, BD, Bk1, a2k * a2k, Di2u, e)
                # stored compactly: D_k^-1 is symmetric (10 words), B1 = B_{k-1,k} has a zero last row (12)
                factor_inv[kk] = Di_packed
                factor_up[kk] = B1
                factor_rhs[kk] = wk
                # slide the windows down one particle
                Di2u = upper3_packed(Di1p)
                Di1p = Di_packed
                Bk1 = B1
                u2 = vec3(u1[0], u1[1], u1[2])
                u1 = unpack_symmetric(Di_packed) * wk
                rho_hi = rho_mid
                rho_mid = rho_lo
                kt_hi = kt_k
                if wp.static(prior):
                    c_hi = corrections_in[kk]
                xk = xk1
                xk1 = xk2

        # ---- C: back substitution root -> tip, follow-the-leader, velocities, tensions ------------
        if wp.static(PHASE_C):
            z1 = vec4()
            z2 = vec4()
            leader = root_new
            leader_old = root_old
            kprev = k0s
            vprev = zero3
            for k in range(1, n):
                kk = particle(base, stride, k)
                # z_k = D_k^-1 (w_k - B1^T z_{k-1} - B2^T z_{k-2}), D_k^-1 symmetric
                yk = factor_rhs[kk]
                if k >= 2:
                    yk = yk - wp.transpose(factor_up[kk]) * vec3(z1[0], z1[1], z1[2])
                if k >= 3:
                    a2 = h2 * k2[particle(base, stride, k - 2)]
                    yk = yk - vec4(a2 * z2[0], a2 * z2[1], a2 * z2[2], real(0.0))
                zk = unpack_symmetric(factor_inv[kk]) * yk
                z2 = z1
                z1 = zk
                x_old = ld(positions_in[kk])
                p = x_old + h * vec3(zk[0], zk[1], zk[2])
                d = p - leader
                dn = wp.length(d)
                x = leader + length[kk] * wp.normalize(x_old - leader_old)
                if dn > real(1.0e-30):
                    x = leader + (length[kk] / dn) * d
                c = x - p
                if wp.static(COLLIDE):
                    # the featured DFTL sweep's response: rounds of collide-then-restore-rest-length, the
                    # first continuous; contact changes the position (so the velocity) only, not c or T
                    xs = st(x)
                    xo = positions_in[kk]
                    lead_s = st(leader)
                    rest_s = scalar(length[kk])
                    radius = features.particle_radius[kk]
                    for it in range(features.collider_iterations):
                        xs, touched = collide_all(features, xs, xo, lead_s, rest_s, it == 0, radius)
                        if not touched:
                            break
                        dc = ld(xs) - leader
                        dcn = wp.length(dc)
                        if dcn > real(1.0e-30):
                            x = leader + (length[kk] / dcn) * dc
                        xs = st(x)
                v = (x - x_old) / h
                positions_out[kk] = st(x)
                # the multiplier of segment k is h T_k: A v + h J^T T = r, the tension pulling particle k
                # back toward its leader (T > 0 under tension, as the rest tensions; the string stiffness
                # max(T, 0) / l of the next step is that of a taut segment)
                tensions_out[kk] = scalar(zk[3] / h)
                if wp.static(prior):
                    corrections_out[kk] = st(c)
                    velocities_out[kk] = st(v)
                else:
                    if k >= 2:
                        velocities_out[kprev] = st(vprev - damping * c / h)
                    vprev = v
                    kprev = kk
                leader = x
                leader_old = x_old
            if wp.static(not prior):
                velocities_out[kprev] = st(vprev)

    return elastic_step
