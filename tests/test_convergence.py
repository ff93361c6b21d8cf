"""The seed's claims (../shared/seed/dftl-analysis.txt) as tests.

1. the prior (eq. 4-6) and posterior (eq. 1-3) corrections give the same positions;
2. with s = 1, DFTL converges at first order to the true inextensible-chain dynamics (the
   reference solver) on the falling horizontal chain;
3. with s < 1 it does not converge, and at small steps it becomes unstable.

Error norm (docs/accuracy.md): ``max over the frames t_k in (0, T] of the RMS over particles of
|x_dftl(t_k) - x_ref(t_k)|``, divided by the chain length, with T = 0.5 s: the chain (1 m, 10
particles) falls from horizontal to about vertical; beyond, the tip whips and trajectories of
any first-order method separate by O(L), hiding the asymptotic rate.
"""

import warnings

import numpy as np
import pytest

import dftl_warp as dw
from dftl_warp.study import scenarios as sc
from dftl_warp.simulation.monitor import EnergyGrowthWarning, EnergyMonitor
from dftl_warp.solvers.reference import ReferenceSolver

G = (0.0, -sc.GRAVITY, 0.0)
LENGTH, PARTICLES, HORIZON, FRAMES = 1.0, 10, 0.5, 20
SUBSTEPS = [10, 20, 40, 80, 160]  # dt = 2.5 ms ... 0.156 ms: four halvings


def falling_chain(solver_name, substeps, **options):
    pts = sc.horizontal_chain(PARTICLES, LENGTH)
    model = dw.Model.from_strands(pts, [PARTICLES], precision="float64")
    solver = dw.make_solver(model, solver_name, gravity=G, **options)
    return sc.record(solver, FRAMES, HORIZON / FRAMES, substeps)[0]


@pytest.fixture(scope="module")
def reference():
    fine = falling_chain("reference", 2560)
    coarse = falling_chain("reference", 1280)
    # the reference's own error is negligible next to any DFTL error measured here
    assert trajectory_error(coarse, fine) < 1e-6
    return fine


def trajectory_error(x, ref):
    """max over frames of the RMS over particles of the position error, / chain length."""
    return float(np.sqrt(((x - ref) ** 2).sum(-1).mean(-1)).max() / LENGTH)


def errors(reference, damping, correction="prior"):
    return np.array([trajectory_error(falling_chain("dftl", k, damping=damping, correction=correction), reference)
                     for k in SUBSTEPS])


def fitted_slope(errs):
    dts = HORIZON / FRAMES / np.array(SUBSTEPS)
    return float(np.polyfit(np.log(dts), np.log(errs), 1)[0])


@pytest.mark.parametrize("damping", [1.0, 0.8, 0.5])
def test_prior_and_posterior_give_the_same_positions(damping):
    pts, counts = sc.groom(strands=12, particles=9)
    roots0 = pts[sc.strand_starts(counts)]
    runs = {}
    for correction in ("prior", "posterior"):
        model = dw.Model.from_strands(pts, counts, precision="float64")
        solver = dw.DFTLSolver(model, damping=damping, correction=correction, gravity=G)
        runs[correction] = sc.record(solver, 24, 1 / 24, 10, roots=lambda t: sc.head_roots(roots0, t))
    assert np.abs(runs["prior"][0] - runs["posterior"][0]).max() < 1e-10
    if damping > 0:
        # the velocities differ: the posterior form subtracts s dx/dt
        assert np.abs(runs["prior"][1] - runs["posterior"][1]).max() > 1e-3


def test_s1_converges_at_first_order(reference):
    errs = errors(reference, 1.0)
    slope = fitted_slope(errs)
    assert 0.8 <= slope <= 1.2, (errs, slope)
    # every halving helps: the local rates approach 1
    local = np.log2(errs[:-1] / errs[1:])
    assert np.all(local > 0.8) and np.all(local < 1.2), local
    # the posterior form has the same positions, hence the same error
    assert np.allclose(errors(reference, 1.0, "posterior"), errs, rtol=1e-6)


@pytest.mark.parametrize("damping", [0.9, 0.8])
def test_s_below_1_does_not_converge(reference, damping):
    errs = errors(reference, damping)
    converged = errors(reference, 1.0)
    # halving the step four times does not reduce the error: it stalls at several % of the length
    assert abs(fitted_slope(errs)) < 0.3, errs
    assert errs[-1] > 0.5 * errs[0]
    assert errs.min() > 0.05
    assert errs[-1] > 20 * converged[-1]


def hanging_strand(particles, length=0.2, nudge=1e-4):
    """A strand hanging from the origin, its tip displaced by ``nudge`` of its length."""
    pts = np.zeros((particles, 3))
    pts[:, 1] = -np.linspace(0.0, length, particles)
    pts[:, 0] = nudge * length * np.linspace(0.0, 1.0, particles) ** 2
    return pts


def run_hanging(particles, damping, dt, seconds=1.0, frames=24, nudge=1e-4, precision="float32"):
    model = dw.Model.from_strands(hanging_strand(particles, nudge=nudge), [particles], precision=precision)
    solver = dw.DFTLSolver(model, damping=damping, gravity=G)
    state, control = solver.state(), model.control()
    monitor = EnergyMonitor(solver, f"dftl s={damping} dt={dt:g} s, {particles} particles", state)
    substeps = max(1, int(round(seconds / frames / dt)))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        for f in range(frames):
            solver.advance(state, control, seconds / frames / substeps, substeps)
            monitor.check(state, f + 1)
    energy = np.array([e for _, e, _ in monitor.history])
    lengths = np.linalg.norm(np.diff(state.positions.numpy(), axis=0), axis=1)
    return monitor, energy, lengths, [w for w in caught if issubclass(w.category, EnergyGrowthWarning)]


@pytest.mark.parametrize("damping,particles", [(0.8, 128), (0.9, 256)])
def test_s_below_1_becomes_unstable_at_small_steps(damping, particles):
    """A strand hanging at rest (up to a 20-micrometre nudge): at 1/240 s it stays at rest; at
    1e-4 s the same setting pumps energy into it until it thrashes, and the monitor says so."""
    seg = 0.2 / (particles - 1)
    monitor, energy, lengths, caught = run_hanging(particles, damping, 1 / 240)
    assert not caught and not monitor.warned
    assert energy.max() < 10 * max(energy[0], 1e-9)

    monitor, energy, lengths, caught = run_hanging(particles, damping, 1e-4)
    assert len(caught) == 1  # warned once ...
    assert f"s={damping}" in str(caught[0].message) and "dt=0.0001" in str(caught[0].message)  # ... naming the setting
    assert energy.max() > 1e3 * energy[0]  # grown from rest by three orders of magnitude or more
    assert np.isfinite(energy).all()
    # the strand keeps its length while it thrashes: the energy is in its motion
    assert np.abs(lengths / seg - 1).max() < 1e-3

    # s = 1 at the same small step is stable: its energy stays at the float32 rounding floor (tens
    # of uJ/kg here, changing from frame to frame without trend) where s < 1 grew it a thousandfold
    monitor, energy, _, caught = run_hanging(particles, 1.0, 1e-4)
    assert not caught and not monitor.warned
    assert energy.max() < 10 * max(energy[0], 1e-9)


@pytest.mark.parametrize("precision", ["float32", "float64"])
def test_s1_dissipates_at_small_steps(precision):
    """With s = 1 at 1e-4 s, a strand swinging well above the rounding floor (tip 4 cm aside)
    loses energy and keeps its length; in float64 frame after frame (float32 positions make
    ``(x - x_old) / dt`` good to ~1e-4 at this step, and its energy wanders by ~1% between frames)."""
    monitor, energy, lengths, caught = run_hanging(128, 1.0, 1e-4, nudge=0.2, precision=precision)
    assert not caught and not monitor.warned
    assert energy[0] > 1e4 * 1e-4  # far above the float32 floor of the hanging strand (~5e-5 J/kg)
    assert energy[-1] < 0.8 * energy[0]
    assert energy.max() < 1.02 * energy[0]
    if precision == "float64":
        assert (np.diff(energy) < 0).all()
    rest = np.linalg.norm(np.diff(hanging_strand(128, nudge=0.2), axis=0), axis=1)
    assert np.abs(lengths / rest - 1).max() < 1e-4
