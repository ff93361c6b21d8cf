"""The reference solver with the elastic solver's energy (RATTLE, float64) against physics: the
large-deflection elastica, the first bending frequency of a cantilever, second-order energy
conservation, an independent integration of the same equations (scipy), and the elastic solver
converging to it."""

from __future__ import annotations

import numpy as np
import pytest
from elastica import cantilever

import dftl_warp as dw
from dftl_warp.solvers.elastic import HAIR_DENSITY, HAIR_E
from dftl_warp.solvers.reference import ReferenceSolver
from dftl_warp.study import scenarios as sc
from dftl_warp.study.sweeps import trajectory_error

R = 40e-6          # 80 um hair
N = 32             # segments
EI = HAIR_E * np.pi * R ** 4 / 4
RHO_A = HAIR_DENSITY * np.pi * R ** 2
WL = RHO_A * sc.GRAVITY
LB = (EI / WL) ** (1.0 / 3.0)   # bending length, 4.93 cm
G = (0.0, -sc.GRAVITY, 0.0)


def straight(L, segments=N):
    rest = np.zeros((segments + 1, 3))
    rest[:, 0] = np.linspace(0.0, L, segments + 1)
    return rest


def helix(L=0.2, turns=2.0, radius=0.015, segments=N):
    """A helix hanging down from the origin, ``segments`` equal segments of total length ``L``."""
    return sc.hair_helix(L, turns, radius, segments)


def model_of(rest):
    return dw.Model.from_strands(rest, [rest.shape[0]], precision="float64")


def reference(rest, drag=0.0, **material):
    solver = ReferenceSolver(model_of(rest), gravity=G, elastic=dict(radius=R, **material), drag=drag)
    return solver, solver.state(), solver.model.control()


def elastica(L, s_eval):
    """(x, y) at ``s_eval`` of a horizontal cantilever of this hair under its own weight."""
    return cantilever(L, s_eval, EI, WL)


# ------------------------------------------------------------------------------------ (a) statics
def cantilever_sag(ratio):
    """A cantilever L = ratio l_b released horizontal with drag about 2 x its first frequency
    (Strang-split; drag changes no equilibrium), settled: (distance to the elastica / L, the
    elastica's tip sag / L, the largest speed / (omega1 L), the largest out-of-plane |z| / L)."""
    L = ratio * LB
    omega1 = 1.8751 ** 2 * np.sqrt(EI / (RHO_A * L ** 4))
    solver, state, control = reference(straight(L), drag=2 * omega1, inverse_statics=False)   # about critical
    dt = 0.5 * solver.elastic.step_limit
    solver.advance(state, control, dt, int(round(15 / omega1 / dt)))
    x = solver.model.points_from_device(state.positions)
    xe, ye = elastica(L, np.linspace(0, L, N + 1))
    error = np.linalg.norm(np.c_[xe, ye] - x[:, :2], axis=1).max() / L
    return error, -ye[-1] / L, solver.diagnostics(state)["max_speed"] / (omega1 * L), np.abs(x[:, 2]).max() / L


@pytest.mark.parametrize("ratio", [1.0, 2.0])
def test_cantilever_sags_to_the_elastica(ratio):
    """Settled on the large-deflection elastica within 2% of L; the sag is large (the test
    discriminates) and the strand stays in its plane."""
    error, sag, speed, off_plane = cantilever_sag(ratio)
    assert speed < 1e-5                                     # settled (to ~1e-5 L)
    assert error < 0.02, error
    assert sag > 0.1
    assert off_plane < 1e-12


# --------------------------------------------------------------------------------- (b) frequency
def bending_frequency():
    """L = l_b / 2 released horizontal: (measured / Euler-Bernoulli first angular frequency
    1.8751^2 sqrt(EI / (rho A L^4)), the tip's swing over the last 40 ms / the first 40 ms,
    upward crossings counted) over 0.25 s, tip height sampled every 0.1 ms."""
    L = 0.5 * LB
    omega1 = 1.8751 ** 2 * np.sqrt(EI / (RHO_A * L ** 4))
    solver, state, control = reference(straight(L), inverse_statics=False)
    per_sample = int(np.ceil(1e-4 / (0.5 * solver.elastic.step_limit)))
    dt = 1e-4 / per_sample
    tip = []
    for _ in range(2500):
        solver.advance(state, control, dt, per_sample)
        tip.append(state.positions.numpy()[solver.model.layout.slot_of_point[-1], 1])
    tip = np.array(tip) - np.mean(tip)
    ups = np.flatnonzero((tip[:-1] < 0) & (tip[1:] >= 0))
    t = (ups + tip[ups] / (tip[ups] - tip[ups + 1])) * 1e-4
    omega = 2 * np.pi / np.mean(np.diff(t))
    return omega / omega1, np.ptp(tip[-400:]) / np.ptp(tip[:400]), len(ups)


def test_first_bending_frequency_of_a_short_cantilever():
    """The cantilever swings about its (small) sag at the Euler-Bernoulli first frequency within
    3%; the reference has no numerical damping."""
    ratio, kept, crossings = bending_frequency()
    assert crossings >= 6
    assert abs(ratio - 1) < 0.03, ratio
    assert kept > 0.98


# ------------------------------------------------------------------------------------ (c) energy
def energy_error(rest, fraction, seconds=0.25, **material):
    """max |E(t) - E(0)| / E(0) (kinetic + gravitational + elastic) at dt = fraction x the step limit."""
    solver, state, control = reference(rest, **material)
    dt = fraction * solver.elastic.step_limit
    per = max(1, int(round(0.002 / dt)))
    e0 = solver.energy(state)
    worst = 0.0
    for _ in range(int(seconds / (per * dt))):
        solver.advance(state, control, dt, per)
        worst = max(worst, abs(solver.energy(state) - e0))
    assert solver.diagnostics(state)["frame_residual"] < 1e-10
    return worst / e0


@pytest.mark.parametrize("shape", ["straight", "curly"])
def test_energy_is_conserved_to_second_order(shape):
    """A cantilever L = l_b released horizontal, and a helix with rest curvature (frames) released
    under gravity: the energy error falls 4x per halving of the step (RATTLE is second order; the
    frames at their minimiser make the bending force conservative)."""
    rest = straight(LB) if shape == "straight" else helix()
    coarse, fine = energy_error(rest, 0.8, inverse_statics=False), energy_error(rest, 0.4, inverse_statics=False)
    assert 3.5 < coarse / fine < 4.6, (coarse, fine)
    assert fine < 1e-4


def chain_difference():
    """Largest distance / L over 0.25 s between the elastic reference with equal masses and no
    bending stiffness and the plain reference's chain of unit masses (a 0.2 m strand released
    horizontal)."""
    rest = straight(0.2, 16)
    radius = np.full(17, R)
    radius[-1] = R * np.sqrt(2.0)                           # the tip carries half a segment
    elastic = ReferenceSolver(model_of(rest), gravity=G, elastic=dict(radius=radius, youngs_modulus=1e-9,
                                                                       inverse_statics=False))
    chain = ReferenceSolver(model_of(rest), gravity=G)
    xa, _ = sc.record(elastic, 6, 1 / 24, 20)
    xb, _ = sc.record(chain, 6, 1 / 24, 20)
    return np.abs(xa - xb).max() / 0.2


def test_equal_masses_without_stiffness_are_the_chain_reference():
    """With equal masses (a thicker tip particle) and no bending stiffness, the mass-weighted
    elastic RATTLE is the chain of unit masses of the plain reference."""
    assert chain_difference() < 1e-10


# ------------------------------------------------------- an independent integration of the same ODE
def independent_integration():
    """A helix of 8 segments (5 cm, rest curvature) released under gravity for 30 ms, against
    scipy's DOP853 on the index-1 DAE  M a = m g - dE/dx + J^T lambda,  J a = -|v_j - v_{j-1}|^2,
    the frames minimised in numpy. Returns (the largest distance / L, the largest motion / L, the
    largest difference of the frames, the largest frame torque of the elastic solver's own energy
    at the numpy frames / its scale sum W |b|^2)."""
    from scipy.integrate import solve_ivp

    from dftl_warp.solvers.elastic_rest import expm_so3, quat_to_mat

    n = 8
    rest = helix(0.05, 1.0, 0.01, segments=n)
    solver, state, control = reference(rest, inverse_statics=False)
    grp = solver.elastic.groups[0][2]
    W, Gt, b, Q = grp.W[0], grp.G[0], grp.b[0], grp.Qb[0]
    al, ga, m = grp.alpha[0], grp.gamma[0], grp.m[0]
    ghost, root = grp.ghost[0], rest[0]
    g = np.asarray(G)

    def curvature(x):
        xm = np.vstack([ghost[None], x[:-1]])
        return -al[:, None] * (x[:n] - xm[:n]) + ga[:, None] * (x[1:] - x[:n])

    def axial(P):
        return np.array([P[2, 1] - P[1, 2], P[0, 2] - P[2, 0], P[1, 0] - P[0, 1]])

    def frames(x, F):
        """Newton on the rotation increments (dense gradient and Hessian)."""
        a = curvature(x)
        eye = np.eye(3)
        for _ in range(30):
            grad = np.zeros((n, 3))
            H = np.zeros((n, 3, n, 3))
            for j in range(n):
                c = F[j] @ b[j]
                grad[j] -= W[j] * np.cross(c, a[j])
                H[j, :, j] -= W[j] * (0.5 * (np.outer(a[j], c) + np.outer(c, a[j])) - (a[j] @ c) * eye)
                P = (eye if j == 0 else F[j - 1]) @ Q[j] @ F[j].T
                tr, sym = np.trace(P), 0.5 * (P + P.T)
                grad[j] -= Gt[j] * axial(P)
                H[j, :, j] += Gt[j] * (tr * eye - sym)
                if j > 0:
                    grad[j - 1] += Gt[j] * axial(P)
                    H[j - 1, :, j - 1] += Gt[j] * (tr * eye - sym)
                    H[j, :, j - 1] += Gt[j] * (P - tr * eye)
                    H[j - 1, :, j] += Gt[j] * (P.T - tr * eye)
            step = np.linalg.solve(H.reshape(3 * n, 3 * n), -grad.ravel()).reshape(n, 3)
            F = expm_so3(step) @ F
            if np.abs(step).max() < 1e-14:
                return F
        raise AssertionError("frames did not converge")

    warm = [np.tile(np.eye(3), (n, 1, 1))]

    def rhs(t, y):
        x = np.vstack([root, y[:3 * n].reshape(n, 3)])
        v = np.vstack([np.zeros(3), y[3 * n:].reshape(n, 3)])
        F = warm[0] = frames(x, warm[0])
        rho = W[:, None] * (curvature(x) - np.einsum("jab,jb->ja", F, b))
        grad = np.zeros((n + 1, 3))                      # dE/dx at the minimising frames
        for j in range(n):
            if j > 0:
                grad[j - 1] += al[j] * rho[j]
            grad[j] -= (al[j] + ga[j]) * rho[j]
            grad[j + 1] += ga[j] * rho[j]
        f = m[1:, None] * g - grad[1:]
        r, dv = x[1:] - x[:-1], v[1:] - v[:-1]
        J = np.zeros((n, n, 3))
        for j in range(n):
            J[j, j] = r[j]
            if j > 0:
                J[j, j - 1] = -r[j]
        A = np.einsum("jka,k,lka->jl", J, 1 / m[1:], J)
        lam = np.linalg.solve(A, -(dv ** 2).sum(1) - np.einsum("jka,ka->j", J, f / m[1:, None]))
        acc = (f + np.einsum("jka,j->ka", J, lam)) / m[1:, None]
        return np.concatenate([v[1:].ravel(), acc.ravel()])

    T = 0.03
    sol = solve_ivp(rhs, (0, T), np.concatenate([rest[1:].ravel(), np.zeros(3 * n)]), method="DOP853",
                    rtol=1e-10, atol=1e-13, t_eval=[T])
    assert sol.success, sol.message
    truth = sol.y[:3 * n, -1].reshape(n, 3)
    # the numpy frames minimise the elastic solver's own energy: its gradient in the frames is zero
    x = np.vstack([root, truth])[None]
    F = frames(x[0], warm[0])

    def energy(F):
        return grp.energy(x, np.zeros_like(x), F[None], ghost[None], g)[0]

    eps, scale = 1e-5, np.sum(W * (b ** 2).sum(1))        # J per rad: the frames' torque scale
    torque = 0.0
    for j, k in ((0, 0), (n // 2, 1), (n - 1, 2)):
        e = np.zeros((n, 3))
        e[j, k] = eps
        torque = max(torque, abs(energy(expm_so3(e) @ F) - energy(expm_so3(-e) @ F)) / (2 * eps))
    dt = 0.25 * solver.elastic.step_limit
    solver.advance(state, control, T / int(np.ceil(T / dt)), int(np.ceil(T / dt)))
    x = solver.model.points_from_device(state.positions)[1:]
    q = solver.elastic.frames.numpy()[solver.model.layout.slot_of_point[:n]]
    frame_difference = np.abs(quat_to_mat(q) - frames(np.vstack([root, x]), warm[0])).max()
    return (np.abs(x - truth).max() / 0.05, np.abs(truth - rest[1:]).max() / 0.05, frame_difference,
            torque / scale)


def test_curly_strand_matches_an_independent_integration():
    """A large motion (more than 5% of L in 30 ms) matched to 1e-5 of the length; the numpy
    frames are the minimiser of the elastic solver's own energy (elastic_rest.RodGroup.energy:
    no torque), and the reference's frames are the same."""
    difference, moved, frames, torque = independent_integration()
    assert moved > 0.05
    assert difference < 1e-5, difference
    assert torque < 1e-6 and frames < 1e-6


# ---------------------------------------------------------------- (d) the elastic solver converges
def elastic_errors(rest, frames, frame_dt, substeps, material, **options):
    L = np.linalg.norm(np.diff(rest, axis=0), axis=1).sum()
    ref = ReferenceSolver(model_of(rest), gravity=G, elastic=dict(radius=R, **material))
    truth, _ = sc.record(ref, frames, frame_dt, int(np.ceil(frame_dt / (0.5 * ref.elastic.step_limit))))
    errors = []
    for k in substeps:
        solver = dw.make_solver(model_of(rest), "elastic", gravity=G, radius=R, **material, **options)
        x, _ = sc.record(solver, frames, frame_dt, k)
        errors.append(trajectory_error(x, truth, L))
    return np.array(errors)


def test_elastic_solver_converges_to_the_reference_at_first_order():
    """A cantilever L = l_b released horizontal, 0.25 s: the elastic solver (defaults) against the
    elastic reference; each 4x more substeps divides the error by about 4 (backward Euler)."""
    errors = elastic_errors(straight(LB), 6, 1 / 24, [16, 64, 256], dict(inverse_statics=False))
    ratios = errors[:-1] / errors[1:]
    assert np.all(ratios > 2.5) and ratios[-1] > 3.2, (errors, ratios)
    assert errors[-1] < 0.01


def test_elastic_solver_with_full_correction_converges_on_a_curly_strand():
    """A helix with rest curvature released under gravity (frames at work), 1/8 s: with DFTL's
    correction s = 1 the elastic solver's error against the reference keeps falling, faster and
    faster as the substeps grow (toward first order)."""
    errors = elastic_errors(helix(), 6, 1 / 48, [64, 256, 1024], dict(inverse_statics=False), damping=1.0)
    ratios = errors[:-1] / errors[1:]
    assert ratios[0] > 1.3 and ratios[1] > 2.0 and ratios[1] > ratios[0], (errors, ratios)


# ---------------------------------------------------------------------------- options and limits
def test_a_step_beyond_the_stability_limit_is_refused():
    solver, state, control = reference(straight(LB), inverse_statics=False)
    limit = solver.elastic.step_limit
    # 80 um hair, 1.5 mm segments: omega_max = (4 / l^2) sqrt(EI / (rho A)) within a few percent
    l = LB / N
    assert solver.elastic.omega_max == pytest.approx(4 / l ** 2 * np.sqrt(EI / RHO_A), rel=0.05)
    with pytest.raises(ValueError, match=r"beyond the elastic reference's stability limit .* substeps per 24 fps"):
        solver.advance(state, control, 1 / 24 / 8, 8)
    with pytest.raises(ValueError, match="stability limit"):
        solver.step(state, state, control, 1.01 * limit)
    solver.step(state, state, control, 0.99 * limit)       # just inside: accepted


def test_options_are_checked():
    model = model_of(straight(LB))
    with pytest.raises(ValueError, match="drag .* needs elastic strands"):
        ReferenceSolver(model, drag=1.0)
    with pytest.raises(ValueError, match="unknown option.*stiffness"):
        ReferenceSolver(model, elastic={"stiffness": 2.0})
    with pytest.raises(ValueError, match="youngs_modulus must be"):
        ReferenceSolver(model, elastic={"youngs_modulus": -1.0})
    solver = dw.make_solver(model, "reference", elastic=True, drag=2.0)
    assert solver.elastic.drag == 2.0 and solver.elastic.radius[0] == pytest.approx(40e-6)
    with pytest.raises(ValueError, match="needs elastic strands"):
        dw.make_solver(model, "reference").energy(model.state())


def test_styled_strand_holds_its_shape():
    """Inverse statics (the elastic solver's rest curvatures): the authored helix is the reference's
    equilibrium too."""
    rest = helix()
    solver, state, control = reference(rest)
    dt = 0.5 * solver.elastic.step_limit
    solver.advance(state, control, dt, int(round(0.5 / dt)))
    moved = np.abs(solver.model.points_from_device(state.positions) - rest).max()
    assert moved < 1e-10 * 0.2, moved


if __name__ == "__main__":   # python tests/test_reference_elastic.py: the numbers of docs/elastic.md
    for k in (1.0, 2.0):
        error, sag, speed, _ = cantilever_sag(k)
        print(f"(a) cantilever L = {k:g} l_b: elastica sag {sag:.4f} L, reference off it by {error:.2e} L")
    ratio, kept, _ = bending_frequency()
    print(f"(b) L = l_b/2: omega / omega_EB = {ratio:.4f}, swing kept {kept:.4f} after 0.25 s")
    for name, rest in (("straight L = l_b", straight(LB)), ("helix", helix())):
        e = [energy_error(rest, f, inverse_statics=False) for f in (0.8, 0.4, 0.2)]
        print(f"(c) {name}: energy error {e[0]:.3e} {e[1]:.3e} {e[2]:.3e} at dt = 0.8, 0.4, 0.2 x the limit, "
              f"ratios {e[0] / e[1]:.3f} {e[1] / e[2]:.3f}")
    for name, rest in (("straight L = l_b", straight(LB)), ("helix", helix())):
        grown = []
        for f in (0.99, 1.01):                              # the limit itself, its check switched off
            solver, state, control = reference(rest, inverse_statics=False)
            solver.elastic.check_step = lambda dt: None
            e0 = solver.energy(state)
            solver.advance(state, control, f * solver.elastic.step_limit, int(0.3 / (f * solver.elastic.step_limit)))
            grown.append(solver.energy(state) / e0)
        print(f"    {name}: E(0.3 s) / E(0) = {grown[0]:.6f} at 0.99 x the step limit, {grown[1]:.3g} at 1.01 x")
    print(f"    equal masses, no stiffness, against the chain reference: {chain_difference():.1e} L")
    d, moved, fr, tq = independent_integration()
    print(f"    helix of 8 segments against DOP853: {d:.2e} L after a motion of {moved:.3f} L; frames {fr:.1e}, "
          f"torque {tq:.1e}")
    e = elastic_errors(straight(LB), 6, 1 / 24, [16, 64, 256], dict(inverse_statics=False))
    print("(d) elastic solver, cantilever L = l_b, 0.25 s, 16/64/256 substeps: " + " ".join(f"{v:.3e}" for v in e))
    for s_ in (0.0, 1.0):
        e = elastic_errors(helix(), 6, 1 / 48, [64, 256, 1024], dict(inverse_statics=False), damping=s_)
        print(f"    helix, 1/8 s, s = {s_:g}, 64/256/1024 substeps per 1/48 s: " + " ".join(f"{v:.3e}" for v in e))
    chain = dict(inverse_statics=False, youngs_modulus=1e-6, radius=np.r_[np.full(N, R), R * np.sqrt(2.0)])
    truth, _ = sc.record(ReferenceSolver(model_of(straight(0.2)), gravity=G), 4, 0.01, 400)
    for s_ in (0.0, 1.0):
        e = [trajectory_error(sc.record(dw.make_solver(model_of(straight(0.2)), "elastic", gravity=G, damping=s_,
                                                        **chain), 4, 0.01, k)[0], truth, 0.2) for k in (100, 400, 1600)]
        print(f"    a chain (no stiffness, equal masses, 0.2 m, 40 ms), s = {s_:g}, 100/400/1600 substeps per 10 ms "
              "against the chain reference: " + " ".join(f"{v:.3e}" for v in e))
    rest = helix()                                          # both settled with drag: the same statics
    solver, state, control = reference(rest, drag=20.0, inverse_statics=False)
    dt = 0.5 * solver.elastic.step_limit
    solver.advance(state, control, dt, int(15 / dt))
    elastic = dw.make_solver(model_of(rest), "elastic", gravity=G, radius=R, inverse_statics=False, drag=20.0)
    settled = elastic.state()
    for _ in range(15 * 24):
        elastic.advance(settled, control, 1 / 24 / 8, 8)
    apart = np.abs(elastic.model.points_from_device(settled.positions)
                   - solver.model.points_from_device(state.positions)).max() / 0.2
    print(f"    helix settled under gravity (drag 20/s, 15 s): the elastic solver {apart:.1e} L from the reference")
