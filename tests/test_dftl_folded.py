"""Folded, fast strands (docs/accuracy/folded.md): DFTL with s = 1 can create energy there.

Strands folded tighter than a right angle at every joint and moving fast (as a collider leaves
them) hold their energy under the true dynamics: the RATTLE reference in float64 at a fine step
keeps it to 1e-3. DFTL with s = 1 at 32 substeps a frame settles into a thrash in which its
particles move most of a segment every step and the strands hold several times that energy; the
energy monitor flags them, and ``simulate`` advises the elastic solver for DFTL with s = 1 (before,
it advised more substeps, which makes this worse: 64 substeps thrash harder than 32). The
elastic solver, whose rest shape is the fold, loses energy from the same start.
"""

import importlib.util
from pathlib import Path

import numpy as np
import pytest
from usd_stages import add_curves, chain, new_stage

from dftl_warp.simulation.settings import SimulationOptions
from dftl_warp.simulation.simulate import Simulation
from dftl_warp.study.scenarios import folded_strands
from dftl_warp.usd.read import read_scene

SCRIPT = Path(__file__).resolve().parents[1] / "scripts" / "probe_dftl_folded.py"
STRANDS, POINTS, SEGMENT, FPS, FRAMES = 4, 16, 0.005, 24, 8


def _probe():
    spec = importlib.util.spec_from_file_location("probe_dftl_folded", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


PROBE = _probe()


def run(kind, substeps):
    """Per frame and strand, the available energy (J/kg, summed over particles) and the RMS speed,
    and the strands the monitor flagged (the probe's runs, on 4 strands for 8 frames)."""
    positions, velocities = folded_strands(STRANDS, POINTS, SEGMENT, speed=0.7, seed=1)
    return PROBE.run_solver(kind, positions, velocities, STRANDS, substeps, frames=FRAMES)


@pytest.fixture(scope="module")
def true_energy():
    energies, _, flagged = run("reference", 512)
    drift = np.abs(energies / energies[0] - 1.0).max()
    assert drift < 1e-3 and not flagged.any(), drift   # the true dynamics keeps its energy
    return energies[0]


def test_dftl_s1_thrashes_from_folded_fast_starts_and_the_monitor_flags_it(true_energy):
    energies, speeds, flagged = run("dftl", 32)
    ratio = energies.max(axis=0) / true_energy
    assert (ratio > 3.0).all(), ratio
    # the thrash: the particles move about a segment every step (not a blow-up: the speed is bounded)
    per_step = speeds[FRAMES // 2:].mean(axis=0) / FPS / 32 / SEGMENT
    assert ((per_step > 0.5) & (per_step < 1.5)).all(), per_step
    assert flagged.all(), flagged


def test_the_elastic_solver_loses_energy_from_the_same_start(true_energy):
    energies, _, flagged = run("elastic", 32)
    assert (energies.max(axis=0) < true_energy).all() and not flagged.any()


def test_dftl_at_s1_advises_the_elastic_solver(tmp_path):
    """The warning's advice for DFTL with s = 1 names the elastic solver, not more substeps."""
    stage = new_stage(tmp_path / "in.usda", start=1, end=2)
    add_curves(stage, "/World/Hair", chain(8, 0.01, direction=(1.0, 0.0, 0.0)), [8])
    stage.Save()
    advice = {}
    for solver, damping in (("dftl", 1.0), ("dftl", 0.5), ("pbd", 1.0)):
        sim = Simulation(read_scene(str(tmp_path / "in.usda")),
                         SimulationOptions(device="cpu", solver=solver, damping=damping), frame=1)
        advice[(solver, damping)] = sim.groups[0].monitor.advice
    assert "elastic solver" in advice[("dftl", 1.0)] and "more substeps" not in advice[("dftl", 1.0)], advice
    assert "use s = 1" in advice[("dftl", 0.5)], advice
    assert "more substeps" in advice[("pbd", 1.0)], advice
