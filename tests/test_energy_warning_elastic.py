"""The energy-growth warning counts an elastic strand's bending and twist energy.

Before, the energy check (dftl_warp.simulation.monitor) counted kinetic and gravitational energy only.
Elastic strands store energy in their bending: thick (2 mm) strands bent around a sphere that passes
through them spring back when it has gone, and the check called the setting unstable ('energy grew to
20.9 J/kg at frame 21, more than 11.2 J/kg ... this setting is unstable') at 32 substeps a frame and
at 128. Now an elastic strand's energy is the solver's total, kinetic, gravitational and elastic (the
quantity the scheme conserves), above the elastic energy of its rest shape, per unit of its mean
particle mass.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from test_energy_warning_colliders import _per_strand, add_collider, grown_lines, through_the_hair
from test_energy_warning_resume import simulate_frames
from usd_stages import add_curves, chain, new_stage

from dftl_warp import cli
from dftl_warp.core.model import Model
from dftl_warp.simulation.monitor import EnergyGrowthWarning, EnergyMonitor
from dftl_warp.solvers import make_solver
from dftl_warp.study.scenarios import hair_helix

G = 9.81


def _elastic(rests, **options):
    model = Model.from_strands(np.concatenate(rests), [len(r) for r in rests], precision="float64")
    solver = make_solver(model, "elastic", radius=4e-5, gravity=(0.0, -G, 0.0), **options)
    return model, solver, solver.state(), model.control()


def _mean_masses(model, solver) -> np.ndarray:
    """Per input strand: the mean mass of its free particles (kg)."""
    mass = solver._fields["mass"].numpy()[model.layout.slot_of_point]
    starts = np.concatenate([[0], np.cumsum(model.counts)])
    return np.array([mass[a + 1:b].mean() for a, b in zip(starts[:-1], starts[1:])])


def test_an_elastic_strands_energy_is_the_solvers_total():
    """Two curls and a straight strand released horizontal without their inverse statics swing
    under gravity: per strand the check's energy times the mean particle mass is the solver's
    kinetic + gravitational + elastic energy (solver.energy, on the host), and it never rises (the
    scheme dissipates)."""
    straight = np.zeros((12, 3))
    straight[:, 0] = np.linspace(0.0, 0.1, 12)
    rests = [hair_helix(0.1, 3.0, 0.005, 24), hair_helix(0.08, 2.0, 0.006, 16), straight]
    model, solver, state, control = _elastic(rests, inverse_statics=False)
    monitor = EnergyMonitor(solver, "elastic", state)
    masses = _mean_masses(model, solver)
    totals = []
    for frame in range(12):
        solver.advance(state, control, 1.0 / 192.0, 8)
        assert not monitor.check(state, frame)
        energy, _, _ = monitor.verdicts()
        assert np.sum(energy * masses) == pytest.approx(solver.energy(state), rel=1e-9)
        totals.append(energy)
    totals = np.array(totals)
    assert np.all(np.diff(totals, axis=0) <= 1e-3 * totals[0]), totals


def test_a_bent_strand_let_go_turns_its_bending_into_motion_without_a_warning():
    """Without gravity, a strand bent into a quarter circle whose rest shape is straight springs
    straight: its bending energy becomes motion (the kinetic energy alone rises from 0 to most of
    it), and the total never rises, so the check stays silent. Before, it counted the motion
    only and called the setting unstable."""
    n, L = 17, 0.1
    angle = np.linspace(0.0, 0.5 * np.pi, n)
    radius = L / (0.5 * np.pi)
    arc = np.stack([radius * np.sin(angle), radius * (1.0 - np.cos(angle)), np.zeros(n)], axis=1)
    straight = np.zeros((n, 3))
    straight[:, 0] = np.linspace(0.0, L, n) * 2.0 * np.sin(0.25 * np.pi / (n - 1)) * (n - 1) / (0.5 * np.pi)
    model = Model.from_strands(arc, [n], precision="float64")
    solver = make_solver(model, "elastic", radius=4e-5, gravity=(0.0, 0.0, 0.0), rest_shape=straight)
    state, control = solver.state(), model.control()
    monitor = EnergyMonitor(solver, "elastic", state)
    start = monitor.measure(state)[0]
    kinetic = []
    with warnings.catch_warnings():
        warnings.simplefilter("error", EnergyGrowthWarning)
        for frame in range(12):
            solver.advance(state, control, 1.0 / 192.0, 8)
            energy = monitor.measure(state)[0]
            monitor.check(state, frame)
            assert energy <= start * (1.0 + 1e-3), (energy, start)
            v = state.velocities.numpy()[model.layout.slot_of_point][1:]
            kinetic.append(0.5 * np.sum(v * v))
    assert start > 0 and max(kinetic) > 0.3 * start, (start, kinetic)


def test_a_styled_strand_at_rest_has_only_its_potential_energy_above_hanging():
    """A thin strand styled horizontal, held by inverse statics: the bending moments that hold it
    store energy it cannot give away at rest, which the check does not count, so its budget is as
    tight as a chain's: its energy at rest is sum m_i g L_i / m (L_i the length from the root, the
    tip particle half a segment's mass), and a strand given speed from nowhere warns."""
    n, spacing = 33, 0.01
    model, solver, state, control = _elastic([chain(n, spacing)])
    monitor = EnergyMonitor(solver, "elastic", state)
    weights = np.ones(n - 1)
    weights[-1] = 0.5
    weights /= weights.mean()
    along = spacing * np.arange(1, n)
    assert monitor.measure(state)[0] == pytest.approx(G * np.sum(weights * along), rel=1e-6)
    for frame in range(3):
        solver.advance(state, control, 1.0 / 192.0, 8)
        assert not monitor.check(state, frame)
    v = state.velocities.numpy()
    v[model.layout.slot_of_point[1:]] += (0.0, 0.0, 2.0)   # 2 m/s out of nowhere: 2 J/kg a particle
    state.write("velocities", v)
    with pytest.warns(EnergyGrowthWarning, match="energy grew"):
        monitor.check(state, 3)


def _struck_stage(path, end):
    """9 strands 30 cm long and 2 mm thick hanging still, a sphere passing through them at 1 m/s."""
    stage = new_stage(path, start=1, end=end)
    pts = np.concatenate([chain(16, 0.02, direction=(0.0, -1.0, 0.0), origin=(x, 0.0, z))
                          for x in (-0.02, 0.0, 0.02) for z in (-0.02, 0.0, 0.02)])
    add_curves(stage, "/World/Hair", pts, [16] * 9, widths=0.002, bending=True)
    add_collider(stage, "sphere", through_the_hair(1.0, end))
    stage.Save()
    return path


def test_thick_strands_bent_by_a_sphere_and_let_go_are_not_called_unstable(tmp_path, capsys):
    """The sphere bends the stiff strands around it as it passes and lets them go: they spring back
    with the energy it stored in them, at fine steps (32 substeps a frame) as at the default."""
    path = _struck_stage(tmp_path / "in.usda", 36)
    for substeps in ("8", "32"):
        assert cli.main(["simulate", str(path), "-o", str(tmp_path / f"{substeps}.usdc"),
                         "--substeps", substeps]) == 0
        err = capsys.readouterr().err
        assert not grown_lines(err), err


def test_resumed_elastic_run_keeps_its_stored_energy_records(tmp_path):
    """A run resumed after the sphere bent the strands continues with the same records (the
    largest elastic energy the sphere stored among them), on one device and two; a checkpoint whose
    records count no elastic energy (saved before the check did) restarts the check."""
    path = _struck_stage(tmp_path / "in.usda", 24)
    for device in ("cpu", "cpu,cpu"):
        whole, want = simulate_frames(path, device, 20)
        first, before = simulate_frames(path, device, 14)
        resumed, after = simulate_frames(path, device, 20, first.save_state())
        assert before + after == want == [], (before, after, want)
        for name in ("collider_speed", "worst_ratio", "stored_energy"):
            np.testing.assert_array_equal(*(_per_strand(s.groups[0].monitor, name) for s in (whole, resumed)))
        assert np.all(_per_strand(whole.groups[0].monitor, "stored_energy") > 0)
    first, _ = simulate_frames(path, "cpu", 14)
    saved = {k: v for k, v in first.save_state().items() if not k.endswith("record7")}
    restarted, _ = simulate_frames(path, "cpu", 14, saved)
    monitor = restarted.groups[0].monitor   # restarted: the loaded state is its start, nothing stored yet
    assert np.all(monitor.stored_energy == 0.0) and np.all(monitor.collider_speed == 0.0)
