"""What the Python API says when a strand blows up: a researcher stepping solvers by hand reads
``solver.diagnostics(state)``; a NaN or infinite particle must show there, not read as a strand at
rest."""

import numpy as np
import pytest

import dftl_warp as dw
from conftest import chain


@pytest.mark.parametrize("field, index", [("positions", 3), ("velocities", 3), ("positions", 0),
                                          ("velocities", 0)])
def test_diagnostics_of_a_non_finite_strand_are_infinite_not_zero(field, index):
    """A strand with one NaN position or velocity reported max_stretch 0.0 and max_speed 0.0
    (``wp.max`` drops a NaN), so a blown-up run read as unstretched and still; now both are
    infinite, for that strand's NaN at its root or inside."""
    points = np.concatenate([chain(5, 0.02), chain(5, 0.02, origin=(0.5, 0, 0))])
    model = dw.Model.from_strands(points, [5, 5], precision="float64")
    solver = dw.make_solver(model, "dftl")
    state = solver.state()
    values = model.points_from_device(getattr(state, field), relative=field == "positions")
    values[5 + index] = np.nan
    state.write(field, model.points_to_device(values, relative=field == "positions"))
    d = solver.diagnostics(state)
    assert d["max_stretch"] == np.inf and d["max_speed"] == np.inf, d
    assert np.isnan(d["energy"]) or index == 0   # the root's energy is not counted


@pytest.mark.parametrize("solver", ["pbd", "reference", "rattle"])
@pytest.mark.parametrize("feature, flag", [
    (lambda F: F.Colliders([F.Sphere(radius=0.05, position=(0.05, -0.06, 0))]), "spheres"),
    (lambda F: F.Drag(5.0), "drag"),
    (lambda F: F.HairHair(cell_size=0.01, friction=2.0), "hair_hair"),
])
def test_solvers_without_features_refuse_a_model_with_them(solver, feature, flag):
    """pbd and reference stepped a model with a sphere, drag or hair-hair as if it had none: the
    strand fell through the sphere, bit for bit the featureless trajectory, without a word (rattle
    already refused). Now all three refuse it, naming the feature."""
    from dftl_warp import features as F

    model = dw.Model.from_strands(chain(6, 0.02), [6], widths=1e-4, features=[feature(F)])
    with pytest.raises(ValueError, match=rf"the {solver} solver steps gravity and roots only; this model has "
                                         rf"features \({flag}\): use --solver dftl"):
        dw.make_solver(model, solver)


@pytest.mark.parametrize("solver", ["pbd", "reference", "rattle"])
def test_solvers_without_features_follow_roots_bound_to_a_mesh(solver):
    """Root binding only sets root targets: every solver follows them."""
    from dftl_warp import features as F

    scalp = np.array([[-0.1, 0, -0.1], [0.1, 0, -0.1], [0.0, 0, 0.1]])
    model = dw.Model.from_strands(chain(4, 0.02, direction=(0, -1, 0)), [4],
                                  features=[F.RootBinding(scalp, np.array([[0, 1, 2]]))])
    sim = dw.make_solver(model, solver)
    state, control = sim.state(), model.control()
    control.bind_roots(scalp, scalp + (0.01, 0, 0))
    sim.advance(state, control, 1 / 96, 4)
    np.testing.assert_allclose(model.points_from_device(state.positions)[0], (0.01, 0, 0), atol=1e-6)


def test_elastic_names_the_zero_width_it_cannot_take_as_a_radius():
    """Widths tapered to 0 at the tips are legal for the Model; the elastic solver, whose default
    radius is half of them, said only 'radius must be finite and > 0' though no radius was passed.
    Now it names the point and where the radius came from."""
    widths = np.array([1e-4, 1e-4, 1e-4, 0.0])
    model = dw.Model.from_strands(chain(4, 0.02), [4], widths=widths)
    with pytest.raises(ValueError, match=r"radius\[3\] = 0\.0 \(half the model's widths, point 3\): must be finite "
                                         r"and > 0 \(widths of 0, e\.g\. tapered tips: pass radius=\)"):
        dw.make_solver(model, "elastic")
    with pytest.raises(ValueError, match=r"radius\[1\] = -1\.0 \(radius, point 1\)"):
        dw.make_solver(model, "elastic", radius=[1e-5, -1.0, 1e-5, 1e-5])
    dw.make_solver(model, "elastic", radius=5e-5)   # an explicit radius takes over


def test_damping_and_correction_a_solver_does_not_take_are_warned_about(tmp_path, capsys):
    """`--solver pbd --damping 0.5`, `--solver ftl --damping 0.5` and `--solver reference
    --correction posterior` ran without a word (the solver has no such setting; only --iterations
    was warned about). Now each is one warning naming the solvers that take it; the defaults (what a
    quality preset fills in) and a solver that takes them stay quiet."""
    import shutil
    from pathlib import Path

    from dftl_warp import cli

    src = tmp_path / "chain.usda"
    shutil.copy(Path(__file__).resolve().parents[1] / "scenes" / "chain.usda", src)
    for k, (args, expected) in enumerate([
        (["--solver", "pbd", "--damping", "0.5"], "--damping 0.5 does nothing here: no prim runs the dftl or elastic "
                                                  "solver, whose damping (DFTL's s) it sets (pbd)"),
        (["--solver", "ftl", "--damping", "0.5"], "--damping 0.5 does nothing here: no prim runs the dftl or elastic"),
        (["--solver", "reference", "--correction", "posterior"],
         "--correction posterior does nothing here: no prim runs the dftl, ftl or elastic solver, whose correction "
         "form it sets (reference)"),
        (["--quality", "draft", "--solver", "pbd"], None),
        (["--solver", "dftl", "--damping", "0.5", "--correction", "posterior"], None),
    ]):
        assert cli.main(["simulate", str(src), "-o", str(tmp_path / f"{k}.usdc"), "--end", "2", *args]) == 0
        err = capsys.readouterr().err
        if expected is None:
            assert "does nothing" not in err, err
        else:
            assert err.count("does nothing") == 1 and f"dftl-warp: warning: {expected}" in err, err


def test_simulate_strands_warns_about_damping_its_solver_does_not_take():
    points = chain(4, 0.02)
    with pytest.warns(UserWarning, match=r"damping 0\.5 does nothing here: this run does not use the dftl or "
                                         r"elastic solver, whose damping \(DFTL's s\) it sets \(pbd\)"):
        dw.simulate_strands(points, [4], steps=2, dt=0.01, solver="pbd", damping=0.5)
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        dw.simulate_strands(points, [4], steps=2, dt=0.01, solver="dftl", damping=0.5)
        dw.simulate_strands(points, [4], steps=2, dt=0.01, solver="pbd")


def test_a_prims_damping_its_solver_does_not_take_is_warned_about(tmp_path):
    """A TD's prim with dftl:solver = "pbd" and dftl:damping = 0.5, dftl:correction = "posterior"
    ran pbd without a word about either. Now each is one warning naming the prim; a prim whose
    solver takes them (dftl) and a --damping overriding the prim's stay quiet about the prim."""
    from pxr import Sdf

    from usd_stages import add_curves, new_stage

    stage = new_stage(tmp_path / "in.usda", start=1, end=2)
    points = np.concatenate([chain(4, 0.02, direction=(0, -1, 0), origin=(0.1 * k, 0, 0)) for k in range(2)])
    for name, solver in (("/World/Pbd", "pbd"), ("/World/Dftl", "dftl")):
        add_curves(stage, name, points, [4, 4])
        prim = stage.GetPrimAtPath(name)
        prim.CreateAttribute("dftl:solver", Sdf.ValueTypeNames.Token).Set(solver)
        prim.CreateAttribute("dftl:damping", Sdf.ValueTypeNames.Float).Set(0.5)
        prim.CreateAttribute("dftl:correction", Sdf.ValueTypeNames.Token).Set("posterior")
    stage.Save()
    summary = dw.simulate_usd(tmp_path / "in.usda", tmp_path / "a.usdc")
    lines = [w for w in summary.warnings if "does nothing" in w]
    assert lines == [f"{tmp_path / 'in.usda'}: /World/Pbd: dftl:damping = 0.5 does nothing: its solver, pbd, has no "
                     "damping (DFTL's s)",
                     f"{tmp_path / 'in.usda'}: /World/Pbd: dftl:correction = 'posterior' does nothing: its solver, pbd, "
                     "has no correction form"], lines
    summary = dw.simulate_usd(tmp_path / "in.usda", tmp_path / "b.usdc", damping=0.3, correction="prior")
    assert not [w for w in summary.warnings if "does nothing" in w], summary.warnings


def _root_onto_the_next_particle(solver, precision="float64", **options):
    """A 10-particle strand along x whose root moves exactly one segment along it in one step: at
    the full step's end the root sits on particle 1's old place, where the SHAKE Jacobian of the
    first segment is singular."""
    points = chain(10, 0.01)
    model = dw.Model.from_strands(points, [10], precision=precision)
    sim = dw.make_solver(model, solver, **options)
    state, control = sim.state(), model.control()
    control.set_root_targets(points[:1], points[:1] + (0.01, 0.0, 0.0))
    sim.step(state, state, control, 1 / 96)
    return model.points_from_device(state.positions), sim.diagnostics(state)


def test_a_nan_newton_solve_is_not_taken_for_converged():
    """The reference's Newton residual was accumulated with wp.max, which drops a NaN: a singular
    solve read as residual 0, was accepted, and the strand was NaN from a finite input (reported as
    constraint_residual 0). rattle's likewise accepted it and its projection hid the NaN: a wrong
    step, counted neither as a fallback nor in the residual. Now both split the step, as for any
    failed solve, and agree."""
    reference, d = _root_onto_the_next_particle("reference")
    assert np.isfinite(reference).all() and d["constraint_residual"] < 1e-12, d
    assert np.isfinite(d["max_speed"])
    for on_chip in (False, True):
        rattle, d = _root_onto_the_next_particle("rattle", on_chip=on_chip)
        assert d["fallbacks"] == 0 and d["constraint_residual"] > 0, d
        np.testing.assert_allclose(rattle, reference, atol=1e-6)


def test_a_nan_clamp_target_is_named_and_changes_nothing():
    """ElasticSolver.set_clamp_targets with a NaN row said 'root targets: row 1 is not finite' (the
    user passed clamp targets) after it had already reset the clamps' path and rotations. Now it
    names the clamp targets and the solver steps exactly as if the call had not been made."""
    points = np.concatenate([chain(5, 0.02), chain(5, 0.02, origin=(0, 0, 0.1))])
    model = dw.Model.from_strands(points, [5, 5], precision="float64")
    runs = []
    for bad in (False, True):
        sim = dw.make_solver(model, "elastic")
        state, control = sim.state(), model.control()
        ghosts = sim.authored_clamps + (0.0, 0.01, 0.0)
        turn = np.tile(np.array([[0.0, -1, 0], [1, 0, 0], [0, 0, 1]]), (2, 1, 1))
        sim.set_clamp_targets(ghosts, rotation_start=turn)
        if bad:
            with pytest.raises(ValueError, match=r"clamp targets \(start\): row 1 is not finite"):
                sim.set_clamp_targets(np.where([[0, 0, 0], [1, 0, 0]], np.nan, ghosts))
        sim.advance(state, control, 1 / 96, 2)
        runs.append(model.points_from_device(state.positions))
    np.testing.assert_array_equal(runs[0], runs[1])


def test_roots_moved_in_place_between_frames_move():
    """`roots += step; control.set_root_targets(roots)` frame after frame left the roots at the
    first frame's targets: the Control reused its device copy of the previous call's end because
    the array was the same object, though its values had moved. Now the roots follow it."""
    points = np.concatenate([chain(4, 0.01, direction=(0, -1, 0)), chain(4, 0.01, direction=(0, -1, 0),
                                                                          origin=(0.1, 0, 0))])
    model = dw.Model.from_strands(points, [4, 4], precision="float64")
    sim = dw.make_solver(model, "dftl")
    state, control = sim.state(), model.control()
    roots = points[[0, 4]].copy()
    for _ in range(5):
        roots += (0.01, 0.0, 0.002)
        control.set_root_targets(roots)
        sim.advance(state, control, 1 / 96, 4)
        np.testing.assert_allclose(model.points_from_device(state.positions)[[0, 4]], roots, atol=1e-15)
    start = roots.copy()
    roots[1] += 0.05                                   # start = the last end by value, a new end in place
    control.set_root_targets(start, roots)
    np.testing.assert_allclose(control.root_start.numpy(), model.roots_to_device(start))
    np.testing.assert_allclose(control.root_end.numpy(), model.roots_to_device(roots))


# -- a step that blows up: advance stays silent (no read-back), the run-level APIs warn ---------------

def _two_chains():
    return np.concatenate([chain(5, 0.01), chain(5, 0.01, origin=(0.5, 0, 0))]), [5, 5]


def test_advance_does_not_read_back_and_diagnostics_show_the_blow_up():
    """``advance`` checks its arguments, not its results (it would have to wait for the device):
    pbd at dt = 1e6 s flies off to 1e13 m without a word there, as documented, and
    ``diagnostics`` reports it."""
    import warnings

    model = dw.Model.from_strands(*_two_chains(), precision="float64")
    solver = dw.make_solver(model, "pbd")
    assert "results are not checked" in " ".join(type(solver).advance.__doc__.split())
    state = solver.state()
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        solver.advance(state, model.control(), 1.0e6, 4)
    assert np.abs(model.points_from_device(state.positions)).max() > 1e6
    assert solver.diagnostics(state)["max_stretch"] > 1e3


@pytest.mark.parametrize("record_every, step", [(1, 1), (2, 2)])
def test_simulate_strands_warns_when_a_particle_flies_off(record_every, step):
    """simulate_strands(dt=1e6) returned frames 1e13 m away (pbd; the reference went to NaN on the
    CPU and to 1e152 m on CUDA before its fallback) without a word; it reads every recorded frame
    back anyway, so it now says so once, with the energy monitor's warning class and words: a
    non-finite value, or a particle farther from its root than 100 strand lengths, named with how
    far (the words for a non-finite one: the test below)."""
    from dftl_warp.simulation.monitor import EnergyGrowthWarning

    points, counts = _two_chains()
    with pytest.warns(EnergyGrowthWarning, match=rf"^simulate_strands: pbd, dt=1e\+06 s: strand 0 \(and 1 more\): "
                                                 rf"a particle \S+ times its length from its root at step {step}; "
                                                 r"this setting is unstable \(a smaller dt may hold it\)$") as caught:
        rec = dw.simulate_strands(points, counts, steps=4, dt=1.0e6, solver="pbd", record_every=record_every)
    assert len([w for w in caught if w.category is EnergyGrowthWarning]) == 1
    assert np.isfinite(rec.positions).all()


def test_the_reference_follows_the_leader_where_no_piece_of_a_step_converges():
    """The reference at dt = 1 s (and 1e6 s) took its failed Newton result once the halving reached
    dt * 1e-6 and went to NaN (1e152 m on CUDA); the rest of such a substep is now one
    follow-the-leader projection: finite, every length exact, and the residual infinite, where a
    step that converges is RATTLE as before (residual at round-off)."""
    for dt, residual in ((1.0 / 240, 1e-12), (1.0, np.inf), (1.0e6, np.inf)):
        model = dw.Model.from_strands(*_two_chains(), precision="float64")
        solver = dw.make_solver(model, "reference")
        state = solver.state()
        solver.advance(state, model.control(), dt, 4)
        points = model.points_from_device(state.positions)
        lengths = np.linalg.norm(np.diff(points.reshape(2, 5, 3), axis=1), axis=2)
        assert np.abs(lengths - 0.01).max() < 1e-12, (dt, lengths)
        assert np.isfinite(model.points_from_device(state.velocities, relative=False)).all()
        d = solver.diagnostics(state)
        assert (d["constraint_residual"] == np.inf) if residual == np.inf else d["constraint_residual"] < residual, d


def test_simulate_strands_names_the_first_step_and_strand_that_is_not_finite():
    from dftl_warp.simulation.strands import Recording, blow_up_note

    positions, velocities = np.zeros((4, 12, 3)), np.zeros((4, 12, 3))
    velocities[2, 7, 1] = np.inf            # frame 2, point 7: strand 1 of counts [5, 3, 4]
    positions[3, 9, 0] = np.nan             # later, strand 2 as well
    line = blow_up_note(Recording(positions, velocities), np.array([5, 3, 4]), 3, "run")
    assert line == ("run: strand 1: non-finite positions or velocities at step 6; this setting is unstable "
                    "(a smaller dt may hold it)")
    positions[2, 0, 2] = np.nan
    assert "strand 0 (and 1 more): non-finite positions or velocities at step 6" in blow_up_note(
        Recording(positions, velocities), np.array([5, 3, 4]), 3, "run")
    assert blow_up_note(Recording(np.zeros((2, 12, 3)), np.zeros((2, 12, 3))), np.array([5, 3, 4]), 1, "run") is None
    chains = np.zeros((3, 12, 3))
    chains[:, :, 0] = np.arange(12) * 0.01            # 3 strands of 5, 3, 4 points 1 cm apart
    chains[2, 9, 1] = 10.0                             # frame 2: strand 2 (3 cm long) 10 m from its root
    assert blow_up_note(Recording(chains, np.zeros_like(chains)), np.array([5, 3, 4]), 1, "run") == (
        "run: strand 2: a particle 333 times its length from its root at step 2; this setting is unstable "
        "(a smaller dt may hold it)")
    chains[2, 9, 1] = 1.0                              # 33 lengths: within the bound
    assert blow_up_note(Recording(chains, np.zeros_like(chains)), np.array([5, 3, 4]), 1, "run") is None


def test_a_stable_simulate_strands_run_does_not_warn():
    import warnings

    from dftl_warp.simulation.monitor import EnergyGrowthWarning

    with warnings.catch_warnings():
        warnings.simplefilter("error", EnergyGrowthWarning)
        dw.simulate_strands(*_two_chains(), steps=3, dt=1.0 / 240)


def test_a_simulation_warns_when_its_state_goes_non_finite(tmp_path):
    """The Simulation's energy monitor, checked once a frame when the samples are read back, names
    a non-finite state: a NaN velocity written into pbd's state (which keeps it; DFTL, the elastic
    and the reference solvers put such a particle back on its segment within a step)."""
    from usd_stages import add_curves, new_stage

    from dftl_warp.simulation.settings import SimulationOptions
    from dftl_warp.simulation.simulate import Simulation

    stage = new_stage(tmp_path / "blow.usda", start=1, end=4)
    add_curves(stage, "/World/Hair", *_two_chains())
    stage.GetRootLayer().Save()
    sim = Simulation(dw.read_scene(str(tmp_path / "blow.usda")),
                     SimulationOptions(solver="pbd", precision="float64", device="cpu"), 1)
    sim.advance()
    sim.samples()
    assert sim.warnings == []
    group = sim.groups[0]
    velocities = group.model.points_from_device(group.state.velocities, relative=False)
    velocities[7] = np.nan                                # strand 1, point 2
    group.state.write("velocities", group.model.points_to_device(velocities, relative=False))
    sim.advance()
    sim.samples()
    assert len(sim.warnings) == 1, sim.warnings
    assert sim.warnings[0].startswith(f"{tmp_path / 'blow.usda'}: /World/Hair: pbd")
    assert "strand 1: non-finite positions or velocities at frame 3; this setting is unstable" in sim.warnings[0]
