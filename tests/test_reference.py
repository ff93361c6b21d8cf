"""The reference solver (RATTLE) against analytic answers; the PBD competitor's behaviour."""

import numpy as np
import pytest

import dftl_warp as dw
from dftl_warp.study import scenarios as sc
from dftl_warp.solvers.pbd import PBDSolver
from dftl_warp.solvers.reference import ReferenceSolver

from conftest import segment_lengths

G = sc.GRAVITY


def upward_crossings(signal, dt):
    """Times (s) where ``signal`` (sampled every ``dt``) crosses zero upwards, interpolated."""
    i = np.flatnonzero((signal[:-1] < 0) & (signal[1:] >= 0))
    return (i - signal[i] / (signal[i + 1] - signal[i])) * dt


def test_elliptic_integral_by_agm():
    assert sc.elliptic_k(0.0) == pytest.approx(np.pi / 2, rel=1e-15)
    # K(1/sqrt(2)) = Gamma(1/4)^2 / (4 sqrt(pi))
    assert sc.elliptic_k(2**-0.5) == pytest.approx(1.8540746773013719, rel=1e-14)
    # the small-amplitude limit is 2 pi sqrt(l/g)
    assert sc.pendulum_period(1.0, G, 1e-6) == pytest.approx(2 * np.pi / np.sqrt(G), rel=1e-12)


@pytest.mark.parametrize("amplitude", [1.0, 2.5])
def test_pendulum_large_amplitude_period(amplitude):
    length = 0.7
    period = sc.pendulum_period(length, G, amplitude)
    model = dw.Model.from_strands(sc.pendulum(length, amplitude), [2], precision="float64")
    solver = ReferenceSolver(model, gravity=(0, -G, 0))
    steps_per_period = 500
    dt = period / steps_per_period
    pos, _ = sc.record(solver, 3 * steps_per_period + 10, dt, 1)
    crossings = upward_crossings(pos[:, 1, 0], dt)
    assert len(crossings) >= 3
    measured = np.diff(crossings)
    # second order: the period error is ~ (omega dt)^2 / 24, far below 1e-4 here
    assert np.abs(measured / period - 1).max() < 1e-4
    # the small-angle formula would be far off: the test discriminates
    assert abs(2 * np.pi * np.sqrt(length / G) / period - 1) > 0.05


@pytest.mark.parametrize("mode", [0, 1, 2, 4])
def test_hanging_chain_mode_period_and_amplitude(mode):
    masses, segment = 5, 0.2
    omega, shapes = sc.hanging_chain_modes(masses, segment)
    amplitude = 1e-3
    pts = sc.hanging_chain_in_mode(masses, segment, shapes[:, mode], amplitude)
    model = dw.Model.from_strands(pts, [masses + 1], precision="float64")
    solver = ReferenceSolver(model, gravity=(0, -G, 0))
    rate = 200.0  # steps per second
    period = 2 * np.pi / omega[mode]
    steps = int(np.ceil(8 * period * rate))
    pos, _ = sc.record(solver, steps, 1 / rate, 1)
    modal = pos[:, 1:, 0] @ shapes[:, mode]  # modal coordinate (shapes are orthonormal)
    crossings = upward_crossings(modal, 1 / rate)
    assert len(crossings) >= 6
    measured = (crossings[-1] - crossings[0]) / (len(crossings) - 1)
    assert abs(measured / period - 1) < 0.002
    # not damped away: the last period swings as far as the first
    per = int(np.ceil(period * rate))
    first, last = np.abs(modal[:per]).max(), np.abs(modal[-per:]).max()
    assert last > 0.98 * first
    assert first == pytest.approx(amplitude, rel=0.02)
    # it stays in its mode: the other modes are not excited
    others = np.delete(shapes, mode, axis=1)
    assert np.abs(pos[:, 1:, 0] @ others).max() < 0.02 * amplitude


def pendulum_energy_error(steps_per_period, periods, amplitude, length=1.0):
    """max |E(t) - E(0)| (J/kg) over ``periods`` periods, sampled at phases that drift through
    the period; also the same over the first and the last tenth of the run."""
    period = sc.pendulum_period(length, G, amplitude)
    model = dw.Model.from_strands(sc.pendulum(length, amplitude), [2], precision="float64")
    solver = ReferenceSolver(model, gravity=(0, -G, 0))
    state, control = solver.state(), model.control()
    dt = period / steps_per_period
    chunk = 7 * steps_per_period // 100
    samples = (steps_per_period * periods) // chunk
    energy = np.empty(samples + 1)

    def total(state):
        x, v = state.positions.numpy()[1], state.velocities.numpy()[1]
        return 0.5 * v @ v + G * x[1]

    energy[0] = total(state)
    for k in range(samples):
        solver.advance(state, control, dt, chunk)
        energy[k + 1] = total(state)
    err = np.abs(energy - energy[0])
    tenth = samples // 10
    return err.max(), err[:tenth].max(), err[-tenth:].max()


@pytest.mark.parametrize("amplitude,scale", [
    # small swing, error relative to the swing's own energy (potential zero at the bottom):
    # velocity Verlet's bound on a harmonic oscillator is (omega dt)^2 / 4 = 9.87e-4 here
    (0.1, "swing"),
    # large swing (57 degrees), error relative to the pendulum's energy scale m g l
    (1.0, "mgl"),
])
def test_pendulum_energy_bounded_and_second_order(amplitude, scale):
    length = 1.0
    norm = G * length * ((1 - np.cos(amplitude)) if scale == "swing" else 1.0)
    coarse, coarse_first, coarse_last = pendulum_energy_error(100, 1000, amplitude, length)
    fine, _, _ = pendulum_energy_error(200, 1000, amplitude, length)
    assert coarse / norm < 1e-3
    # bounded, no drift over 1000 periods: the last hundred periods are no worse than the first
    assert coarse_last < 1.01 * coarse_first
    # second order: halving the step divides the error by about 4
    assert 3.8 < coarse / fine < 4.2


def test_reference_keeps_constraints_to_round_off(rng):
    counts = np.array([2, 7, 33])
    pts = np.concatenate([np.cumsum(rng.normal(size=(n, 3)) * 0.03, axis=0) for n in counts])
    model = dw.Model.from_strands(pts, counts, precision="float64")
    solver = ReferenceSolver(model, gravity=(0, -G, 0))
    roots0 = pts[sc.strand_starts(counts)]
    pos, vel = sc.record(solver, 30, 1 / 60, 8, roots=lambda t: roots0 + [0.2 * np.sin(5 * t), 0, 0.1 * t])
    rest = segment_lengths(pts, counts)
    assert np.abs(segment_lengths(pos, counts) / rest - 1).max() < 1e-12
    assert solver.diagnostics(solver.state())["constraint_residual"] < 1e-12
    # velocities are tangent to the constraints: no segment stretches at any rate
    seg = np.diff(pos[-1], axis=0)
    rate = np.einsum("ij,ij->i", seg, np.diff(vel[-1], axis=0))
    keep = np.ones(len(seg), dtype=bool)
    keep[sc.strand_starts(counts)[1:] - 1] = False
    assert np.abs(rate[keep]).max() < 1e-10
    # the roots followed their targets
    assert np.allclose(pos[-1, sc.strand_starts(counts)], roots0 + [0.2 * np.sin(2.5), 0, 0.05], atol=1e-12)


def test_reference_advance_equals_steps():
    pts = sc.horizontal_chain(9, 0.4)
    model = dw.Model.from_strands(pts, [9], precision="float64")
    a, b = ReferenceSolver(model), ReferenceSolver(model)
    sa, sb = a.state(), b.state()
    control = model.control()
    a.advance(sa, control, 1e-3, 50)
    for _ in range(50):
        b.step(sb, sb, control, 1e-3)
    assert np.array_equal(sa.positions.numpy(), sb.positions.numpy())
    assert np.array_equal(sa.velocities.numpy(), sb.velocities.numpy())


def test_reference_refuses_zero_rest_length():
    pts = np.array([[0, 0, 0], [0, 0, 0], [0.1, 0, 0]], dtype=float)
    with pytest.raises(ValueError, match="non-zero rest lengths"):
        ReferenceSolver(dw.Model.from_strands(pts, [3], precision="float64"))


def test_make_solver_knows_pbd_and_reference():
    model = dw.Model.from_strands(sc.horizontal_chain(4), [4], precision="float64")
    assert isinstance(dw.make_solver(model, "pbd", iterations=3, damping=1.0), PBDSolver)
    assert dw.make_solver(model, "pbd", iterations=3).iterations == 3
    assert isinstance(dw.make_solver(model, "reference", correction="prior"), ReferenceSolver)
    rec = dw.simulate_strands(sc.horizontal_chain(4), [4], steps=10, dt=1e-2, solver="reference", precision="float64")
    assert np.isfinite(rec.positions).all()
    with pytest.raises(ValueError, match="iterations"):
        PBDSolver(model, iterations=0)


def test_pbd_stretches_and_more_iterations_stretch_less():
    """The competitor's signature: a long chain hanging under its weight stretches with few
    Gauss-Seidel sweeps; more sweeps stretch less; DFTL does not stretch at all."""
    pts = sc.horizontal_chain(64, 1.0)
    stretch = {}
    for k in (1, 4, 16):
        model = dw.Model.from_strands(pts, [64], precision="float64")
        solver = PBDSolver(model, iterations=k, gravity=(0, -G, 0))
        pos, _ = sc.record(solver, 48, 1 / 24, 4)
        stretch[k] = segment_lengths(pos[-1], [64]).sum() / 1.0 - 1
        assert np.isfinite(pos).all()
        # the root is pinned
        assert np.array_equal(pos[:, 0], np.zeros((49, 3)))
    assert stretch[1] > 0.5  # a one-sweep chain more than half again as long as its rest length
    assert stretch[1] > stretch[4] > stretch[16] > 0.005
    dftl = dw.DFTLSolver(dw.Model.from_strands(pts, [64], precision="float64"), gravity=(0, -G, 0))
    pos, _ = sc.record(dftl, 48, 1 / 24, 4)
    assert abs(segment_lengths(pos[-1], [64]).sum() - 1) < 1e-12
