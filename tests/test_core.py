"""Core DFTL solver: inextensibility, the two correction forms, dynamics, roots, robustness."""

import numpy as np
import pytest
import warp as wp

import dftl_warp as dw
from dftl_warp.solvers import numpy_baseline as baseline
from dftl_warp.core.layout import make_layout

from conftest import chain, segment_lengths

G = (0.0, -9.81, 0.0)


def random_groom(rng, counts, spacing=0.02):
    pts = []
    for n in counts:
        steps = rng.normal(size=(n, 3))
        steps /= np.linalg.norm(steps, axis=1, keepdims=True)
        steps[0] = rng.uniform(-0.1, 0.1, size=3) / spacing
        pts.append(np.cumsum(steps * spacing, axis=0))
    return np.concatenate(pts), np.asarray(counts)


@pytest.mark.parametrize("precision,tol", [("float32", 1e-5), ("float64", 1e-12)])
@pytest.mark.parametrize("dt", [1 / 24, 1e-5])
@pytest.mark.parametrize("correction", ["prior", "posterior"])
def test_segment_lengths_exact_after_1000_steps(precision, tol, dt, correction, rng):
    pts, counts = random_groom(rng, [2, 5, 16, 31])
    rest = segment_lengths(pts, counts)
    rec = dw.simulate_strands(pts, counts, steps=1000, dt=dt, gravity=G, correction=correction,
                              precision=precision, record_every=1000)
    rel = np.abs(segment_lengths(rec.positions[-1], counts) / rest - 1.0)
    assert rec.positions.shape == (2, counts.sum(), 3)
    assert np.isfinite(rec.positions).all()
    assert rel.max() < tol
    # it moved: the strands fell under gravity
    assert np.abs(rec.positions[-1] - pts).max() > (1e-9 if dt < 1e-3 else 1e-2)


def test_prior_and_posterior_positions_agree():
    pts = chain(100, spacing=0.01)
    kw = dict(steps=500, dt=1e-3, gravity=G, precision="float64", record_every=10)
    prior = dw.simulate_strands(pts, [100], correction="prior", **kw)
    posterior = dw.simulate_strands(pts, [100], correction="posterior", **kw)
    assert np.abs(prior.positions - posterior.positions).max() < 1e-10
    # ... while their velocities differ: the posterior form subtracts s dx/dt
    assert np.abs(prior.velocities - posterior.velocities).max() > 1e-3


@pytest.mark.parametrize("correction", ["prior", "posterior"])
def test_pendulum_small_amplitude_period(correction):
    length, g, theta0 = 0.5, 9.81, 0.05
    pts = np.array([[0.0, 0.0, 0.0], [length * np.sin(theta0), -length * np.cos(theta0), 0.0]])
    dt = 1e-4
    steps = 40000  # about 2.8 periods
    rec = dw.simulate_strands(pts, [2], steps=steps, dt=dt, gravity=(0, -g, 0), correction=correction,
                              precision="float64")
    x = rec.positions[:, 1, 0]
    t = np.arange(x.shape[0]) * dt
    # upward zero crossings of x, linearly interpolated
    i = np.flatnonzero((x[:-1] < 0) & (x[1:] >= 0))
    crossings = t[i] - x[i] * dt / (x[i + 1] - x[i])
    period = np.mean(np.diff(crossings))
    expected = 2 * np.pi * np.sqrt(length / g)
    assert len(crossings) >= 2
    assert abs(period / expected - 1) < 0.005


def test_roots_follow_kinematic_targets_exactly(rng):
    pts, counts = random_groom(rng, [1, 4, 9, 3])
    steps = 40
    t = np.arange(steps + 1)[:, None, None] * 0.01
    starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
    roots = pts[starts][None] + np.concatenate([np.sin(3 * t), np.cos(2 * t) - 1, 0.5 * t], axis=2) * 0.125
    for precision in ("float32", "float64"):
        rec = dw.simulate_strands(pts, counts, steps=steps, dt=0.01, gravity=G, precision=precision, roots=roots)
        expected = roots.astype(precision).astype(np.float64)
        assert np.array_equal(rec.positions[:, starts], expected)
        # the one-vertex strand is its root and nothing else
        assert np.array_equal(rec.positions[:, 0], expected[:, 0])
        rest = segment_lengths(pts, counts)
        assert np.abs(segment_lengths(rec.positions[-1], counts) / rest - 1).max() < 1e-5


def test_identical_runs_are_bitwise_identical(rng):
    pts, counts = random_groom(rng, [7, 3, 12])
    a = dw.simulate_strands(pts, counts, steps=200, dt=1 / 240, gravity=G)
    b = dw.simulate_strands(pts, counts, steps=200, dt=1 / 240, gravity=G)
    assert np.array_equal(a.positions, b.positions) and np.array_equal(a.velocities, b.velocities)


@pytest.mark.parametrize("precision", ["float32", "float64"])
@pytest.mark.parametrize("offset", [0.0, 1e-20, 1e-9])
def test_degenerate_predictions_stay_finite(precision, offset):
    """Velocities that carry every particle exactly (or nearly) onto its leader."""
    n, dt = 6, 1e-2
    pts = chain(n, spacing=0.05)
    vel = np.zeros_like(pts)
    vel[1:] = (pts[:-1] - pts[1:]) / dt
    vel[1:, 1] += offset / dt
    rec = dw.simulate_strands(pts, [n], steps=20, dt=dt, gravity=(0, 0, 0), precision=precision,
                              velocities=vel)
    assert np.isfinite(rec.positions).all() and np.isfinite(rec.velocities).all()
    tol = 1e-5 if precision == "float32" else 1e-12
    assert np.abs(segment_lengths(rec.positions, [n]) / 0.05 - 1).max() < tol


@pytest.mark.parametrize("precision", ["float32", "float64"])
def test_degenerate_threshold_is_relative_to_the_rest_length(precision):
    """A prediction within rest * 1e-6 (float32; 1e-12 float64) of its leader keeps the segment's
    previous direction; one a little farther takes its own direction."""
    rest, dt = 2.0**-4, 2.0**-4  # powers of two: the prediction lands where it is put, unrounded
    pts = np.array([[0.0, 0.0, 0.0], [rest, 0.0, 0.0]])
    tiny = 1e-8 if precision == "float32" else 1e-14
    for distance, expected in ((rest * tiny, [rest, 0.0, 0.0]), (rest * 1e-3, [0.0, rest, 0.0])):
        vel = np.zeros_like(pts)
        vel[1] = (np.array([0.0, distance, 0.0]) - pts[1]) / dt  # predicted onto (or near) the root
        rec = dw.simulate_strands(pts, [2], steps=1, dt=dt, gravity=(0, 0, 0), precision=precision,
                                  velocities=vel)
        np.testing.assert_allclose(rec.positions[-1][1], expected, atol=1e-7)


def test_coincident_input_points_stay_finite():
    """Zero-length rest segments: the followers sit on their leader, without NaN."""
    pts = np.array([[0, 0, 0], [0, 0, 0], [0.1, 0, 0], [0.1, 0, 0]], dtype=float)
    rec = dw.simulate_strands(pts, [4], steps=50, dt=1e-2, gravity=G)
    assert np.isfinite(rec.positions).all() and np.isfinite(rec.velocities).all()
    lengths = segment_lengths(rec.positions[-1], [4])
    assert np.allclose(lengths, [0.0, 0.1, 0.0], atol=1e-6)


@pytest.mark.parametrize("correction", ["prior", "posterior"])
def test_numpy_baseline_agrees(correction, rng):
    pts, counts = random_groom(rng, [1, 2, 5, 9, 17])
    for layout in ("strand-major", "particle-major"):
        rec = dw.simulate_strands(pts, counts, steps=100, dt=1 / 120, gravity=G, correction=correction,
                                  precision="float64", layout=layout, record_every=100)
        x, v = baseline.simulate(pts, counts, steps=100, dt=1 / 120, gravity=G, correction=correction)
        assert np.abs(rec.positions[-1] - x).max() < 1e-10
        assert np.abs(rec.velocities[-1] - v).max() < 1e-10


def test_layouts_give_bitwise_identical_results(rng):
    pts, counts = random_groom(rng, [3, 8, 3, 1, 8, 5])
    runs = [dw.simulate_strands(pts, counts, steps=60, dt=1 / 60, gravity=G, layout=name)
            for name in ("strand-major", "particle-major")]
    assert np.array_equal(runs[0].positions, runs[1].positions)
    assert np.array_equal(runs[0].velocities, runs[1].velocities)


def test_particle_major_layout_is_coalesced():
    lay = make_layout(np.array([3, 2, 3]), "particle-major")
    assert lay.groups == ((2, 0, 1), (3, 1, 2))
    # particle i of the two 3-vertex strands sit side by side
    slots = lay.slot_of_point
    assert list(slots) == [2, 4, 6, 0, 1, 3, 5, 7]
    assert sorted(slots) == list(range(8))


def test_particle_major_warps_hold_strands_that_are_neighbours_in_space(rng):
    """Given the roots, a particle-major group orders its strands along the Morton curve of the
    roots: 32 consecutive device strands (a warp) of a shuffled 64 x 64 grid of roots span a few grid
    cells, not the whole grid; strands of other counts stay in their own group."""
    side = 64
    grid = np.stack(np.meshgrid(np.arange(side), np.arange(side)), -1).reshape(-1, 2).astype(float)
    roots = np.c_[grid[:, 0], np.zeros(len(grid)), grid[:, 1]][rng.permutation(len(grid))]
    counts = np.full(len(grid), 5)
    counts[:10] = 3
    lay = make_layout(counts, "particle-major", roots=roots)
    assert lay.groups == ((3, 0, 10), (5, 10, len(grid) - 10))
    assert sorted(lay.strand_order[:10]) == list(range(10))
    ordered = roots[lay.strand_order[10:]]
    warps = ordered[: (len(ordered) // 32) * 32].reshape(-1, 32, 3)
    spread = np.linalg.norm(warps.max(axis=1) - warps.min(axis=1), axis=1)
    shuffled = roots[10:][: warps.shape[0] * 32].reshape(-1, 32, 3)
    assert np.median(spread) < 12 < np.median(np.linalg.norm(shuffled.max(axis=1) - shuffled.min(axis=1), axis=1))
    assert sorted(lay.slot_of_point) == list(range(int(counts.sum())))


def test_interleaved_layout_gives_each_field_its_own_slots():
    counts = np.array([3, 2, 3] + [4] * 40)
    lay = make_layout(counts, "particle-major", interleave=3)
    assert lay.interleave == 3 and lay.chunk_slots == 96
    slots = lay.slot_of_point
    fields = np.concatenate([slots + 32 * f for f in range(3)])
    assert np.unique(fields).size == fields.size  # no two fields of any particles share a slot
    assert fields.max() < lay.num_slots + 64 and lay.num_slots % 96 == 0
    # particle i of neighbouring strands of one group sit side by side, each field 32 slots on
    s = lay.strand_base
    first = lay.groups[-1][1]
    assert s[first + 1] == s[first] + 1 and s[first + 32] == s[first] + 96
    with pytest.raises(ValueError, match="cannot interleave"):
        make_layout(counts, "strand-major", interleave=3)


@pytest.mark.parametrize("correction", ["prior", "posterior"])
def test_interleaved_states_are_views_of_one_buffer(correction, rng):
    pts, counts = random_groom(rng, [5, 7, 5, 2])
    model = dw.Model.from_strands(pts, counts, precision="float64", layout="particle-major", interleave=3)
    solver = dw.DFTLSolver(model, gravity=G, correction=correction)
    state, control = solver.state(), model.control()
    assert state.storage is not None and state.positions.shape[0] == model.num_slots
    assert model.num_points == counts.sum() < model.num_slots
    assert np.array_equal(model.points_from_device(state.positions), pts)
    v = rng.normal(size=pts.shape)
    state.write("velocities", model.points_to_device(v, relative=False))
    assert np.array_equal(model.points_from_device(state.positions), pts)  # untouched by the write
    assert np.array_equal(model.points_from_device(state.velocities, relative=False), v)
    copy = state.clone()
    solver.advance(state, control, 1 / 240, 3)
    other = solver.state()
    other.assign(state)
    for name in ("positions", "velocities"):
        assert np.array_equal(getattr(other, name).numpy(), getattr(state, name).numpy())
    assert np.array_equal(model.points_from_device(copy.velocities, relative=False), v)  # the clone is its own
    # same motion as the plain particle-major layout
    plain = dw.Model.from_strands(pts, counts, precision="float64", layout="particle-major", interleave=1)
    psolver = dw.DFTLSolver(plain, gravity=G, correction=correction)
    pstate = psolver.state()
    pstate.write("velocities", plain.points_to_device(v, relative=False))
    psolver.advance(pstate, plain.control(), 1 / 240, 3)
    assert np.array_equal(plain.points_from_device(pstate.positions), model.points_from_device(state.positions))
    assert np.array_equal(plain.points_from_device(pstate.velocities), model.points_from_device(state.velocities))
    if correction == "prior":
        state.write("corrections", None, zero=True)
        assert not state.corrections.numpy()[model.layout.slot_of_point].any()
        assert np.array_equal(plain.points_from_device(pstate.positions), model.points_from_device(state.positions))


def test_ftl_solver_is_dftl_without_damping(rng):
    pts, counts = random_groom(rng, [6, 4])
    ftl = dw.simulate_strands(pts, counts, steps=50, dt=1 / 60, gravity=G, solver="ftl", precision="float64")
    s0 = dw.simulate_strands(pts, counts, steps=50, dt=1 / 60, gravity=G, damping=0.0, precision="float64")
    assert np.array_equal(ftl.positions, s0.positions)
    s1 = dw.simulate_strands(pts, counts, steps=50, dt=1 / 60, gravity=G, damping=1.0, precision="float64")
    assert np.abs(ftl.positions - s1.positions).max() > 1e-3


def test_far_from_origin_float32_keeps_lengths():
    pts = chain(20, spacing=0.01, origin=(1e5, 2e5, -1e5))
    rec = dw.simulate_strands(pts, [20], steps=200, dt=1 / 240, gravity=G, precision="float32", record_every=200)
    assert np.abs(segment_lengths(rec.positions[-1], [20]) / 0.01 - 1).max() < 1e-4
    assert rec.positions[-1, -1, 1] < 2e5 - 0.05  # it fell


def test_state_memory_per_particle():
    pts = chain(10)
    for precision, prior_bytes in (("float32", 36), ("float64", 72)):
        model = dw.Model.from_strands(pts, [10], precision=precision)
        assert dw.DFTLSolver(model, correction="prior").state().bytes_per_particle() == prior_bytes
        assert dw.DFTLSolver(model, correction="posterior").state().bytes_per_particle() == prior_bytes * 2 // 3


def test_solver_step_between_two_states(rng):
    pts, counts = random_groom(rng, [5, 7])
    model = dw.Model.from_strands(pts, counts, precision="float64")
    solver = dw.DFTLSolver(model, gravity=G)
    a, b = solver.state(), solver.state()
    control = model.control()
    for _ in range(10):
        solver.step(a, b, control, 0.01)
        a, b = b, a
    in_place = solver.state()
    for _ in range(10):
        solver.step(in_place, in_place, control, 0.01)
    assert np.array_equal(a.positions.numpy(), in_place.positions.numpy())
    assert np.array_equal(a.velocities.numpy(), in_place.velocities.numpy())


def test_diagnostics_report_energy_stretch_speed():
    pts = chain(10, spacing=0.1)
    model = dw.Model.from_strands(pts, [10], precision="float64")
    solver = dw.DFTLSolver(model, gravity=G)
    state, control = solver.state(), model.control()
    d0 = solver.diagnostics(state)
    assert d0["max_speed"] == 0.0 and d0["max_stretch"] < 1e-12 and d0["energy"] == pytest.approx(0.0)
    solver.advance(state, control, 1e-3, 100)
    d1 = solver.diagnostics(state)
    assert d1["max_speed"] > 0.5 and d1["max_stretch"] < 1e-12
    assert d1["energy"] < 1e-9  # DFTL dissipates, never creates energy here


def test_bad_arguments_are_refused():
    with pytest.raises(ValueError, match="strand 1 has 0 vertices"):
        dw.Model.from_strands(chain(3), [3, 0])
    with pytest.raises(ValueError, match="point 1 is not finite"):
        dw.Model.from_strands(np.array([[0, 0, 0], [np.nan, 0, 0]]), [2])
    with pytest.raises(ValueError, match="damping"):
        dw.DFTLSolver(dw.Model.from_strands(chain(3), [3]), damping=1.5)
    with pytest.raises(ValueError, match="unknown solver"):
        dw.make_solver(dw.Model.from_strands(chain(3), [3]), "rk4")


def test_synthetic_groom_states_are_cloned_not_made_at_rest():
    from dftl_warp.core.synthetic import uniform_groom

    model, state = uniform_groom(5, 4, layout="particle-major")
    solver = dw.DFTLSolver(model, gravity=G)
    with pytest.raises(ValueError, match="State.clone"):
        solver.state()
    other = state.clone()
    assert other.positions.ptr != state.positions.ptr
    assert np.array_equal(other.positions.numpy(), state.positions.numpy())
    control = model.control()
    solver.step(state, other, control, 0.01)  # swapped states over a synthetic groom
    solver.step(state, state, control, 0.01)
    assert np.array_equal(other.positions.numpy(), state.positions.numpy())


def test_root_targets_reuse_the_last_end_in_device_order(rng):
    pts, counts = random_groom(rng, [3, 5, 2, 4])
    model = dw.Model.from_strands(pts, counts, layout="particle-major")
    control = model.control()
    a, b, c = (rng.normal(size=(4, 3)) for _ in range(3))
    control.set_root_targets(a, b)
    control.set_root_targets(b, c)  # b again, as the same array: its device copy is reused
    assert np.array_equal(control.root_start.numpy(), model.roots_to_device(b))
    assert np.array_equal(control.root_end.numpy(), model.roots_to_device(c))
    control.set_root_targets(a)  # a held root: start and end the same
    assert np.array_equal(control.root_start.numpy(), model.roots_to_device(a))
    assert np.array_equal(control.root_end.numpy(), model.roots_to_device(a))


def test_interleave_follows_what_the_solver_carries():
    from dftl_warp.core.layout import default_interleave
    from dftl_warp.solvers import carries_corrections

    assert default_interleave("particle-major", "cuda:0") == 3
    assert default_interleave("particle-major", "cuda:0", corrections=False) == 2
    assert default_interleave("particle-major", "cuda:0", features=True) == 1
    assert default_interleave("particle-major", "cpu") == default_interleave("strand-major", "cuda:0") == 1
    assert carries_corrections("dftl", "prior") and carries_corrections("ftl", "prior")
    assert not carries_corrections("dftl", "posterior") and not carries_corrections("pbd", "prior")
    # a posterior model interleaves two vectors; a prior State on it is refused with a clear message
    pts = chain(6)
    model = dw.Model.from_strands(pts, [6], layout="particle-major", interleave=2)
    assert dw.DFTLSolver(model, correction="posterior").state().storage.shape[0] == model.num_slots + 32
    with pytest.raises(ValueError, match="interleaves 2 state vectors"):
        dw.DFTLSolver(model, correction="prior").state()


# -- argument checks (issue 18 item 7) -----------------------------------------------------------


@pytest.mark.parametrize("kwargs, message", [
    ({"dt": float("nan")}, "dt must be a finite number"),
    ({"dt": 0.0}, "dt must be"),
    ({"dt": -1 / 24}, "dt must be"),
    ({"dt": float("inf")}, "dt must be"),
    ({"dt": True}, "dt must be"),
    ({"gravity": (0.0, float("nan"), 0.0)}, "gravity must be 3 finite numbers"),
    ({"gravity": (0.0, -float("inf"), 0.0)}, "gravity must be 3 finite numbers"),
    ({"gravity": (1.0, 2.0)}, "gravity must be 3 finite numbers"),
    ({"steps": -1}, "steps must be an integer >= 0"),
    ({"steps": 2.5}, "steps must be an integer >= 0"),
    ({"record_every": 0}, "record_every must be an integer >= 1"),
    ({"damping": 1.5}, "damping must be in [0, 1]"),
    ({"correction": "later"}, "correction must be one of prior, posterior"),
    ({"solver": "magic"}, "solver must be one of"),
    ({"precision": "float16"}, "precision must be one of float32, float64"),
])
def test_simulate_strands_checks_its_arguments(kwargs, message):
    args = {"steps": 2, "dt": 1 / 24, "gravity": G, **kwargs}
    with pytest.raises(ValueError) as exc:
        dw.simulate_strands(chain(4, 0.1), [4], **args)
    assert message in str(exc.value)


@pytest.mark.parametrize("solver", ["dftl", "ftl", "pbd", "reference"])
def test_every_solver_checks_dt_substeps_and_gravity(solver):
    from dftl_warp.solvers import make_solver

    model = dw.Model.from_strands(chain(4, 0.1), [4], device="cpu", precision="float64")
    sim = make_solver(model, solver, gravity=G)
    state, control = sim.state(), model.control()
    before = state.positions.numpy().copy()
    for dt in (float("nan"), 0.0, -0.01, float("inf"), np.float32("nan")):
        with pytest.raises(ValueError, match="dt must be"):
            sim.advance(state, control, dt, 2)
        with pytest.raises(ValueError, match="dt must be"):
            sim.step(state, state, control, dt)
    for substeps in (0, -1, 2.5, True, "2"):
        with pytest.raises(ValueError, match="substeps must be an integer >= 1"):
            sim.advance(state, control, 1 / 24, substeps)
    np.testing.assert_array_equal(state.positions.numpy(), before)  # nothing ran
    sim.advance(state, control, np.float64(1 / 24), np.int64(2))  # numpy scalars are fine
    assert np.isfinite(state.positions.numpy()).all()
    for g in ((0.0, float("nan"), 0.0), (float("inf"), 0.0, 0.0)):
        with pytest.raises(ValueError, match="gravity must be 3 finite numbers"):
            make_solver(model, solver, gravity=g)


def test_a_new_solver_gets_the_checks_without_a_line_of_its_own():
    from dftl_warp.solvers import Solver

    class Toy(Solver):
        name = "toy-unregistered"

        def step(self, state_in, state_out, control, dt, root_alpha=1.0):
            self.ran = True

    model = dw.Model.from_strands(chain(3, 0.1), [3], device="cpu")
    toy = Toy(model)
    with pytest.raises(ValueError, match="dt must be"):
        toy.step(None, None, None, float("nan"))
    with pytest.raises(ValueError, match="substeps must be"):
        toy.advance(None, None, 0.01, 0)
    with pytest.raises(TypeError, match="state_in must be a dftl_warp.State"):   # and the State/Control check
        toy.step(None, None, None, 0.01)
    state = toy.state()
    toy.step(state, state, model.control(), 0.01)
    assert toy.ran
