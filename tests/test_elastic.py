"""The elastic-rod solver (scheme K) on the CPU: physics checks against the elastica and energy, and
the Warp kernel against an independent numpy step (dense KKT solve) to round-off."""

from __future__ import annotations

import numpy as np
import pytest
import warp as wp
from elastica import cantilever

from dftl_warp.core.model import Model
from dftl_warp.solvers import make_solver
from dftl_warp.solvers.elastic import HAIR_DENSITY, HAIR_E, ElasticSolver
from dftl_warp.solvers.elastic_rest import RodGroup, expm_so3, rotation_between
from dftl_warp.study.scenarios import hair_helix

R = 40e-6          # 80 um hair
N = 32
FPS = 24.0
G0 = 9.81
EI = HAIR_E * np.pi * R ** 4 / 4
WL = HAIR_DENSITY * np.pi * R ** 2 * G0
LB = (EI / WL) ** (1.0 / 3.0)   # bending length, 4.93 cm


def elastica(L, s_eval):
    """(x, y) at ``s_eval`` of a horizontal cantilever of this hair under its own weight."""
    return cantilever(L, s_eval, EI, WL)


def straight(Ls):
    rest = np.zeros((len(Ls), N + 1, 3))
    for k, L in enumerate(Ls):
        rest[k, :, 0] = np.linspace(0, L, N + 1)
    return rest


def helix(L, turns=3.0, radius=0.01):
    """One helix (1, N + 1, 3) hanging from the origin: the study's ``hair_helix``."""
    return hair_helix(L, turns, radius, N)[None]


def setup(rest, precision="float64", **options):
    model = Model.from_strands(rest.reshape(-1, 3), [rest.shape[1]] * rest.shape[0], precision=precision)
    solver = make_solver(model, "elastic", radius=R, **options)
    return model, solver, solver.state(), model.control()


def positions(model, state, shape):
    return model.points_from_device(state.positions).reshape(shape)


def run(solver, state, control, substeps, seconds):
    for _ in range(int(round(seconds * FPS))):
        solver.advance(state, control, 1.0 / (FPS * substeps), substeps)


# ---------------------------------------------------------------------------------------- statics
RATIOS = (0.5, 1.0, 2.0, 4.0)


@pytest.fixture(scope="module")
def cantilever_sags():
    """Tip sag / L of horizontal cantilevers L = RATIOS l_b settled at 2, 8 and 32 substeps (float64)."""
    Ls = np.array(RATIOS) * LB
    out = {}
    for sub in (2, 8, 32):
        model, solver, state, control = setup(straight(Ls), inverse_statics=False, drag=20.0)
        run(solver, state, control, sub, 4.0)          # drag only speeds settling; statics are exact
        out[sub] = positions(model, state, (len(Ls), N + 1, 3))
        speed = np.linalg.norm(model.points_from_device(state.velocities, relative=False), axis=1).max()
        assert speed < 1e-6 * LB, speed
    return Ls, out


def elastica_error(L, x):
    s = np.linspace(0, L, N + 1)
    xe, ye = elastica(L, s)
    return np.linalg.norm(np.c_[xe, ye] - x[:, :2], axis=1).max() / L


@pytest.mark.parametrize("k", range(len(RATIOS)))
def test_cantilever_matches_elastica(cantilever_sags, k):
    Ls, x = cantilever_sags
    assert elastica_error(Ls[k], x[8][k]) < 0.02


def test_cantilever_sag_is_substep_independent(cantilever_sags):
    Ls, x = cantilever_sags
    sags = np.array([x[sub][:, -1, 1] / Ls for sub in (2, 8, 32)])
    assert np.ptp(sags, axis=0).max() < 0.01


@pytest.mark.parametrize("compute", ["float32", "float64"])
def test_float32_statics(compute):
    Ls = np.array([0.5, 2.0]) * LB
    model, solver, state, control = setup(straight(Ls), precision="float32", inverse_statics=False, drag=20.0,
                                          compute_precision=compute)
    run(solver, state, control, 8, 4.0)
    x = positions(model, state, (2, N + 1, 3))
    for k, L in enumerate(Ls):
        assert elastica_error(L, x[k]) < 0.02


# ----------------------------------------------------------------------------- curved rest shapes
@pytest.mark.parametrize("precision,compute", [("float64", None), ("float32", "float32"), ("float32", "float64")])
def test_curly_strand_stays_still_without_gravity(precision, compute):
    rest = helix(0.2)
    model, solver, state, control = setup(rest, precision=precision, gravity=(0.0, 0.0, 0.0),
                                          compute_precision=compute)
    run(solver, state, control, 8, 10.0)
    moved = np.linalg.norm(positions(model, state, rest.shape) - rest, axis=-1).max() / 0.2
    assert moved < 1e-5, moved


@pytest.mark.parametrize("precision,bound", [("float64", 1e-12), ("float32", 1e-7)])
def test_styled_strand_holds_its_shape_under_gravity(precision, bound):
    """Inverse statics: the authored helix is the equilibrium under gravity (float32 storage with
    the default float64 arithmetic: the storage rounding only)."""
    rest = helix(0.2, turns=2.0, radius=0.015)
    model, solver, state, control = setup(rest, precision=precision)
    run(solver, state, control, 8, 1.0)
    moved = np.linalg.norm(positions(model, state, rest.shape) - rest, axis=-1).max() / 0.2
    assert moved < bound, moved


# ---------------------------------------------------------------------------- energy and lengths
@pytest.mark.parametrize("substeps", [1, 8, 32])
def test_energy_never_rises(substeps):
    """A strand L = l_b released horizontal swings down: kinetic + gravitational + elastic energy
    must not rise (backward Euler dissipates)."""
    rest = straight([LB])
    model, solver, state, control = setup(rest, inverse_statics=False)
    E = [solver.energy(state)]
    for _ in range(int(FPS)):
        solver.advance(state, control, 1.0 / (FPS * substeps), substeps)
        E.append(solver.energy(state))
    E = np.array(E)
    rise = np.max(E - np.minimum.accumulate(E)) / E[0]
    assert rise <= 1e-3, rise
    assert E[-1] < E[0]
    assert "elastic_energy" in solver.diagnostics(state)


def test_written_tensions_are_the_weight_below_a_hanging_strand():
    """A straight strand hanging at rest: each segment's written tension is the weight of the hair
    below it, rho A g l (N - k + 1/2) for segment k (the tip particle carries half a segment),
    positive under tension as the inverse-statics rest tensions are; it is the sign the next step's
    string stiffness max(T, 0) / l reads (before, the kernel wrote -T, so that stiffness acted only
    on compressed segments after the first step)."""
    L = 0.2
    rest = np.zeros((1, N + 1, 3))
    rest[0, :, 1] = -np.linspace(0.0, L, N + 1)
    model, solver, state, control = setup(rest, inverse_statics=False)
    run(solver, state, control, 8, 2.0 / FPS)
    T = state.tensions.numpy()[model.layout.slot_of_point][1:]
    weight_below = HAIR_DENSITY * np.pi * R ** 2 * G0 * (L / N) * (N - np.arange(1, N + 1) + 0.5)
    assert np.allclose(T, weight_below, rtol=1e-9, atol=0.0), np.max(np.abs(T / weight_below - 1))


def test_long_curly_strand_keeps_its_energy():
    """A curl of 64 segments (0.1 m, 3 turns of 5 mm, 1.6 mm segments) released without its
    inverse statics at 8 substeps per frame: the energy must not rise. Before the banded solve
    built its Schur complements from the couplings (B D^-1 B^T) instead of the multipliers
    (U D U^T, U = B D^-1), round-off grew by about D's condition at every particle: this strand's
    velocity solve was wrong by 1e21 relative and the strand flailed at metres per second."""
    rest = hair_helix(0.1, 3.0, 0.005, 64)[None]
    model, solver, state, control = setup(rest, inverse_statics=False)
    E = [solver.energy(state)]
    for _ in range(12):
        solver.advance(state, control, 1.0 / (FPS * 8), 8)
        E.append(solver.energy(state))
    E = np.array(E)
    assert np.all(np.isfinite(E))
    rise = np.max(E - np.minimum.accumulate(E)) / abs(E[0])
    assert rise <= 1e-3, rise


@pytest.mark.parametrize("correction", ["prior", "posterior"])
def test_exact_inextensibility_with_a_shaken_root(correction):
    rest = np.concatenate([straight([LB]), helix(0.2)])
    model, solver, state, control = setup(rest, damping=1.0, correction=correction)
    roots = rest[:, 0]
    for f in range(12):
        shake = 0.02 * np.sin(2 * np.pi * 3.0 * (f + 1) / FPS)
        control.set_root_targets(roots if f == 0 else roots + prev, roots + [shake, 0.0, 0.0])
        prev = np.array([shake, 0.0, 0.0])
        solver.advance(state, control, 1.0 / FPS, 1)
    x = positions(model, state, rest.shape)
    err = np.abs(np.linalg.norm(np.diff(x, axis=1), axis=-1) / np.linalg.norm(np.diff(rest, axis=1), axis=-1) - 1)
    assert np.isfinite(x).all() and err.max() < 1e-12, err.max()


def test_rotating_clamp_turns_the_strand():
    """Roots and ghosts rotated together by 90 degrees about the vertical: the stiff short strand
    follows (its tip ends near the rotated rest tip)."""
    L = 0.5 * LB
    rest = straight([L])
    model, solver, state, control = setup(rest, inverse_statics=True, drag=20.0)
    ghost = solver.authored_clamps
    assert np.allclose(ghost, [[-L / N, 0, 0]])
    Rz = expm_so3(np.array([0.0, np.pi / 2, 0.0]))     # about +y
    frames = 24
    for f in range(frames):
        a0, a1 = expm_so3(np.array([0, np.pi / 2 * f / frames, 0])), expm_so3(np.array([0, np.pi / 2 * (f + 1) / frames, 0]))
        solver.set_clamp_targets(ghost @ a0.T, ghost @ a1.T)
        solver.advance(state, control, 1.0 / (FPS * 8), 8)
    run(solver, state, control, 8, 1.0)
    tip = positions(model, state, rest.shape)[0, -1]
    assert np.linalg.norm(tip - Rz @ rest[0, -1]) < 0.01 * L


def test_features_are_refused():
    rest = straight([LB])
    model = Model.from_strands(rest.reshape(-1, 3), [N + 1], precision="float64")
    object.__setattr__(model, "features", (object(),))
    with pytest.raises(ValueError, match="features"):
        ElasticSolver(model)


# ---------------------------------------------------- the kernel against an independent numpy step
def numpy_step(g: RodGroup, st, h, root, gravity, s=0.0, correction="prior", drag=0.0):
    """One scheme-K step in numpy float64 with a *dense* KKT solve (the kernel factors it banded)."""
    S, N_ = g.S, g.N
    x, v, F = st["x"], st["v"], st["F"]
    al, ga, W, l, m = g.alpha, g.gamma, g.W, g.l, g.m
    xg_old, xg_new = st["ghost"], root + (g.ghost - st["root0"])     # the default clamp: moved with the root
    v0 = (root - x[:, 0]) / h
    e = g.directions(x, xg_old)
    Rr = rotation_between(g.d0, root - xg_new)
    Dxn = g.apply_D(x, xg_old)
    for j in range(N_):                              # frames: one Gauss-Seidel sweep
        Fp = Rr if j == 0 else F[:, j - 1]
        M = W[:, j, None, None] * np.einsum('sa,sb->sab', Dxn[:, j], g.b[:, j]) + g.G[:, j, None, None] * (Fp @ g.Qb[:, j])
        if j + 1 < N_:
            M = M + g.G[:, j + 1, None, None] * (F[:, j + 1] @ np.swapaxes(g.Qb[:, j + 1], -1, -2))
        U, _, Vt = np.linalg.svd(M)
        U[..., :, 2] *= np.sign(np.linalg.det(U @ Vt))[..., None]
        F[:, j] = U @ Vt
    xm = np.concatenate([xg_new[:, None], root[:, None], x[:, 1:]], axis=1)
    Dx = -al[..., None] * (xm[:, 1:N_ + 1] - xm[:, :N_]) + ga[..., None] * (xm[:, 2:] - xm[:, 1:N_ + 1])
    rho = W[..., None] * (Dx - np.einsum('sjab,sjb->sja', F, g.b))
    x_new, v_new, T, c = x.copy(), v.copy(), np.zeros((S, N_ + 1)), np.zeros_like(x)
    for q in range(S):
        # f = -D^T rho (particles 1..N), with D's rows j = 0..N-1 acting on particles j-1, j, j+1
        f = m[q, 1:, None] * gravity
        for j in range(N_):
            for i, w_ in ((j - 1, al[q, j]), (j, -al[q, j] - ga[q, j]), (j + 1, ga[q, j])):
                if i >= 1:
                    f[i - 1] -= w_ * rho[q, j]
        Dm = np.zeros((N_, N_ + 2))                  # D on particles (ghost, 0, 1..N) -> columns 1..N
        for j in range(N_):
            Dm[j, j:j + 3] = al[q, j], -al[q, j] - ga[q, j], ga[q, j]
        K = Dm[:, 2:].T @ (W[q][:, None] * Dm[:, 2:])
        kt = np.maximum(st["T"][q, 1:], 0) / l[q, 1:N_ + 1]
        KT = np.diag(kt + np.r_[kt[1:], 0]) - np.diag(kt[1:], 1) - np.diag(kt[1:], -1)
        f[0] += kt[0] * v0[q] * h
        A = np.kron(m[q, 1:, None] * (1 + h * drag) * np.eye(N_) + h * h * (K + KT), np.eye(3))
        J = np.zeros((N_, 3 * N_))
        for k in range(N_):
            J[k, 3 * k:3 * k + 3] = e[q, k + 1]
            if k:
                J[k, 3 * k - 3:3 * k] = -e[q, k + 1]
        xp = x[q].copy()
        if correction == "prior":
            xp[:N_] -= s * st["c"][q, 1:]
        rv = m[q, 1:, None] * (v[q, 1:] + (xp[1:] - x[q, 1:]) / h) + h * f
        z = np.linalg.solve(np.block([[A, J.T], [J, np.zeros((N_, N_))]]),
                            np.r_[rv.ravel(), e[q, 1] @ v0[q], np.zeros(N_ - 1)])
        vt = z[:3 * N_].reshape(N_, 3)
        x_new[q, 0] = root[q]
        for k in range(1, N_ + 1):
            p = x[q, k] + h * vt[k - 1]
            d = p - x_new[q, k - 1]
            x_new[q, k] = x_new[q, k - 1] + l[q, k] / np.linalg.norm(d) * d
            c[q, k] = x_new[q, k] - p
        T[q, 1:] = z[3 * N_:] / h                    # A v + h J^T T = r: T > 0 under tension
    v_new = (x_new - x) / h
    v_new[:, 0] = v0
    if correction == "posterior":
        v_new[:, 1:N_] -= s * c[:, 2:] / h
    st.update(x=x_new, v=v_new, T=T, c=c, F=F, ghost=xg_new)


def kernel_and_numpy_steps(rest, shake, s, correction="prior"):
    """Six 1/192 s steps of strands ``rest`` (S, n, 3) under gravity, float64, roots moved by
    (shake[0] sin(k + 1), shake[1] k, 0) at step k: the kernel's (model, state) and the numpy
    step's state dict."""
    gravity = np.array([0.0, -9.81, 0.0])
    S, n = rest.shape[:2]
    model = Model.from_strands(rest.reshape(-1, 3), [n] * S, precision="float64")
    solver = make_solver(model, "elastic", radius=R, damping=s, correction=correction, gravity=gravity)
    state, control = solver.state(), model.control()
    g = solver._groups[0][2]
    ref = dict(x=rest.copy(), v=np.zeros_like(rest), T=g.T_rest.copy(), c=np.zeros_like(rest),
               F=np.tile(np.eye(3), (S, n - 1, 1, 1)), ghost=g.ghost.copy(), root0=rest[:, 0].copy())
    h = 1.0 / 192
    for k in range(6):
        root = rest[:, 0] + [shake[0] * np.sin(k + 1.0), shake[1] * k, 0.0]
        control.set_root_targets(root)
        solver.step(state, state, control, h)
        numpy_step(g, ref, h, root, gravity, s=s, correction=correction)
    return model, state, ref


@pytest.mark.parametrize("correction", ["prior", "posterior"])
def test_kernel_equals_numpy_step(correction):
    rng = np.random.default_rng(7)
    S, n = 4, 11
    rest = np.zeros((S, n, 3))
    for q in range(S):
        d = np.array([1.0, 0, 0])
        for i in range(1, n):
            d = d + 0.6 * rng.normal(size=3)
            d /= np.linalg.norm(d)
            rest[q, i] = rest[q, i - 1] + 0.01 * (1 + 0.3 * rng.random()) * d
    model, state, ref = kernel_and_numpy_steps(rest, [0.01, 0.004], s=0.5, correction=correction)
    x = positions(model, state, rest.shape)
    v = model.points_from_device(state.velocities, relative=False).reshape(rest.shape)
    T = state.tensions.numpy()[model.layout.slot_of_point].reshape(S, n)
    assert np.abs(x - ref["x"]).max() < 1e-13
    assert np.abs(v - ref["v"]).max() < 1e-10 * np.abs(ref["v"]).max()
    assert np.abs(T - ref["T"]).max() < 1e-10 * np.abs(ref["T"]).max()
    assert wp.get_device("cpu") == model.device


def test_kernel_equals_numpy_step_on_a_long_stiff_strand():
    """The banded KKT solve against the dense one on a curl of 48 stiff segments (0.05 m, 1 mm
    segments of 80 um hair) at 8 substeps per frame, its root moving: equal to round-off. The
    multiplier form of the elimination (U D U^T) gave a relative error of 2e14 on this matrix
    (its condition is about 1e8: the dense solve is exact to ~1e-8 of it)."""
    rest = hair_helix(0.05, 2.0, 0.005, 48)[None]
    model, state, ref = kernel_and_numpy_steps(rest, [0.002, 0.001], s=1.0)
    x = positions(model, state, rest.shape)
    v = model.points_from_device(state.velocities, relative=False).reshape(rest.shape)
    assert np.abs(x - ref["x"]).max() < 1e-10 * 0.05
    assert np.abs(v - ref["v"]).max() < 1e-7 * np.abs(ref["v"]).max()


def test_radius_defaults_to_half_the_model_widths():
    rest = straight([LB])
    model = Model.from_strands(rest.reshape(-1, 3), [N + 1], precision="float64", widths=100e-6)
    assert np.allclose(make_solver(model, "elastic").radius, 50e-6)
    per_point = np.linspace(100e-6, 60e-6, N + 1)   # tapering to the tip
    model = Model.from_strands(rest.reshape(-1, 3), [N + 1], precision="float64", widths=per_point)
    assert np.allclose(make_solver(model, "elastic").radius, per_point / 2)
    plain = Model.from_strands(rest.reshape(-1, 3), [N + 1], precision="float64")
    assert np.allclose(make_solver(plain, "elastic").radius, 40e-6)
