"""DFTL at the extremes: every case keeps its lengths, stays finite, and behaves as
docs/accuracy.md ("Stability at the extremes") says; the energy monitor fires only where the
setting creates energy.

Base case: a 0.2 m strand of 32 particles released horizontally (or hanging), s = 1, float32,
one substep per step; each test moves one setting to its extreme.
"""

import warnings

import numpy as np
import pytest

import dftl_warp as dw
from dftl_warp.study import scenarios as sc
from dftl_warp.simulation.monitor import EnergyGrowthWarning, EnergyMonitor

L = 0.2


def run(pts, counts, *, dt, steps, substeps=1, damping=1.0, precision="float32", gravity=sc.GRAVITY, roots=None):
    """Run DFTL; returns (positions, velocities, monitor, warnings, relative length error, tolerance)."""
    model = dw.Model.from_strands(pts, counts, precision=precision)
    solver = dw.DFTLSolver(model, damping=damping, gravity=(0.0, -gravity, 0.0))
    state = solver.state()
    monitor = EnergyMonitor(solver, f"s={damping} dt={dt:g}", state)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        pos, vel = sc.record(solver, steps // substeps, dt * substeps, substeps, roots=roots, state=state,
                             monitor=monitor)
    counts = np.asarray(counts)
    keep = np.ones(len(pts) - 1, dtype=bool)
    keep[np.cumsum(counts)[:-1] - 1] = False
    rest = np.linalg.norm(np.diff(pts, axis=0), axis=1)[keep]
    lengths = np.linalg.norm(np.diff(pos, axis=1), axis=2)[:, keep]
    error = float(np.abs(lengths / rest - 1).max())
    # round-off bound: a few ulps of the largest device coordinate, relative to the shortest
    # segment, plus the float64 round-off of measuring lengths in world coordinates
    extent = float(np.abs(pos - model.origin).max())
    tolerance = 8 * (np.finfo(precision).eps * (1 + extent / rest.min())
                     + np.finfo(np.float64).eps * float(np.abs(pos).max()) / rest.min())
    grown = [w for w in caught if issubclass(w.category, EnergyGrowthWarning)]
    assert np.isfinite(pos).all() and np.isfinite(vel).all()
    assert error <= tolerance, (error, tolerance)
    return pos, vel, monitor, grown


def diagonal_strand(n=32, length=L):
    """A strand hanging at 45 degrees from the origin."""
    t = np.linspace(0.0, length, n)[:, None]
    return t * np.array([[2**-0.5, -(2**-0.5), 0.0]])


@pytest.mark.parametrize("precision", ["float32", "float64"])
@pytest.mark.parametrize("dt", [1e-6, 1e-4, 1 / 240, 1 / 24])
def test_step_size_from_a_microsecond_to_a_frame(precision, dt):
    steps = 2000 if dt < 1e-3 else 48
    pos, _, monitor, grown = run(sc.horizontal_chain(32, L), [32], dt=dt, steps=steps, precision=precision)
    assert not grown and not monitor.warned
    t = dt * steps
    if dt == 1 / 24:
        # overdamped: a 17 mm fall per step against 6 mm segments; it hangs after 2 s, no swing
        assert pos[-1, -1, 1] == pytest.approx(-L, rel=1e-5)
    if dt == 1e-6:
        # 2 ms: the tip is still in free fall
        assert pos[-1, -1, 1] == pytest.approx(-0.5 * sc.GRAVITY * t * t, rel=0.01)


def test_float32_stalls_when_a_step_moves_less_than_its_resolution():
    """At 1 microsecond a step's fall g dt^2 = 1e-11 m is below float32's resolution of
    coordinates of 0.1 m (7e-9 m): a strand whose coordinates are not near zero does not move.
    float64 moves as it should."""
    moved = {}
    for precision in ("float32", "float64"):
        pos, _, monitor, grown = run(diagonal_strand(), [32], dt=1e-6, steps=2000, precision=precision)
        moved[precision] = np.linalg.norm(pos[-1, -1] - pos[0, -1])
        assert not grown
    assert moved["float64"] > 1e-5
    assert moved["float32"] < 1e-7


@pytest.mark.parametrize("dt,unstable", [(1 / 240, {0.0, 0.5}), (1e-4, {0.0, 0.5, 0.9})])
def test_damping_from_ftl_to_dftl(dt, unstable):
    """s < 1 creates energy, the more so the smaller s and dt; s = 1 never does. Lengths are kept
    and nothing overflows even while the strand thrashes."""
    steps = int(round(1.0 / dt))
    for damping in (0.0, 0.5, 0.9, 1.0):
        _, vel, monitor, grown = run(sc.horizontal_chain(64, L), [64], dt=dt, steps=steps, substeps=steps // 24,
                                     damping=damping)
        assert monitor.warned == (damping in unstable), (damping, monitor.worst_ratio)
        assert len(grown) == int(damping in unstable)
        if damping in unstable:
            assert f"s={damping}" in str(grown[0].message)
        if damping == 1.0:
            assert monitor.worst_ratio.max() < 0.6  # at most 1.2x its start energy, far from a warning


@pytest.mark.parametrize("precision", ["float32", "float64"])
def test_segment_lengths_from_ten_micrometres_to_a_kilometre(precision):
    runs = {}
    for seg in (1e-5, 1e-2, 1e3):
        pts = sc.horizontal_chain(32, 31 * seg)
        pos, _, monitor, grown = run(pts, [32], dt=1 / 240, steps=240, precision=precision)
        assert not grown
        runs[seg] = pos[-1, -1, 1] / (31 * seg)
    # at 1/240 s a 10-micrometre segment (time scale sqrt(l/g) = 1 ms) hangs still within a second,
    # a kilometre segment (10 s) has barely started to fall
    assert runs[1e-5] == pytest.approx(-1.0, abs=1e-6)
    assert -1e-3 < runs[1e3] < 0


def test_dftl_is_scale_invariant():
    """Lengths times k and steps times sqrt(k) give the same motion: 1e-5 m and 1e3 m segments
    are the same simulation at their own time scale (float64)."""
    small = sc.horizontal_chain(16, 15e-5)
    big = sc.horizontal_chain(16, 15e3)
    a = dw.simulate_strands(small, [16], steps=100, dt=1e-4, precision="float64")
    b = dw.simulate_strands(big, [16], steps=100, dt=1e-4 * 1e4, precision="float64")
    assert np.abs(a.positions / 1e-5 - b.positions / 1e3).max() < 1e-9


@pytest.mark.parametrize("particles", [2, 4096])
def test_particles_per_strand_from_2_to_4096(particles):
    pos, _, monitor, grown = run(sc.horizontal_chain(particles, L), [particles], dt=1 / 240, steps=480,
                                 substeps=10)
    assert not grown and not monitor.warned
    tip = pos[:, -1, 1] / L
    if particles == 4096:
        # 49 micrometre segments: the sweep pulls the whole strand at once; it hangs within 2 s
        assert tip[-1] < -0.99
    else:
        # a single pendulum: follow-the-leader barely damps it, it still swings after 2 s
        assert tip[-24:].max() - tip[-24:].min() > 0.2


@pytest.mark.parametrize("precision", ["float32", "float64"])
def test_scene_far_from_the_origin(precision):
    """1e5 m away the Model subtracts a world origin: the same motion as at (0, 0, 0)."""
    pts = sc.horizontal_chain(32, L)
    near, _, _, _ = run(pts, [32], dt=1 / 240, steps=240, precision=precision)
    far, _, monitor, grown = run(pts + 1e5, [32], dt=1 / 240, steps=240, precision=precision)
    assert not grown
    assert np.abs(far - 1e5 - near).max() < (2e-6 if precision == "float32" else 1e-9)


@pytest.mark.parametrize("damping", [1.0, 0.0])
def test_root_teleported_by_100_strand_lengths(damping):
    counts = [32, 32, 32]
    pts = np.concatenate([sc.horizontal_chain(32, L) + [0, 0, 0.01 * i] for i in range(3)])
    roots0 = pts[sc.strand_starts(counts)]
    jump = np.array([100 * L, 0.0, 0.0])

    def roots(t):
        return roots0 + (jump if t > 0.5 / 24 else 0.0)

    pos, vel, monitor, grown = run(pts, counts, dt=1 / 240, steps=960, substeps=10, damping=damping, roots=roots)
    tip = pos[:, 31] - pos[:, 0]
    # frame 1: the strand is dragged in a straight line behind its root (at 480 m/s)
    assert tip[1, 0] < -0.98 * L
    assert np.abs(vel[1]).max() == pytest.approx(100 * L * 24, rel=0.01)
    # frame 2: it overshoots, flipped ahead of the root
    assert tip[2, 0] > 0.5 * L
    # the root's work explains the energy: no warning either way
    assert not grown and not monitor.warned
    if damping == 1.0:
        # 4 s later it hangs at rest below its new root position
        assert np.allclose(tip[-1], [0.0, -L, 0.0], atol=0.01 * L)


@pytest.mark.parametrize("dt", [1e-4, 1 / 240, 1 / 24])
def test_gravity_of_1000_g(dt):
    steps = 2000 if dt < 1e-3 else 48
    pos, _, monitor, grown = run(sc.horizontal_chain(32, L), [32], dt=dt, steps=steps, gravity=1000 * sc.GRAVITY)
    assert not grown and not monitor.warned
    # time scale sqrt(L/g) = 4.5 ms: within 0.2 s it hangs straight down
    assert pos[-1, -1, 1] == pytest.approx(-L, rel=1e-4)
