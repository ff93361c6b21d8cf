"""A run resumed from a saved state (a batch job's checkpoint) warns about energy growth as the
uninterrupted run did.

Before, the energy monitor's records (each strand's start energy, its root's fastest speed, whether it
had already warned) were not in the saved state: a run resumed after the warning warned a second time,
about another frame, and one resumed before it judged the strands against budgets of its own start.
"""

from __future__ import annotations

import numpy as np
import pytest
from usd_stages import add_curves, chain, new_stage

from dftl_warp.simulation.simulate import Simulation, SimulationOptions
from dftl_warp.usd.read import read_scene


def _stage(path):
    # DFTL with s = 0 at 40 substeps a frame pumps energy into horizontal chains (test_stability)
    stage = new_stage(path, start=1, end=12)
    add_curves(stage, "/World/Hair", np.concatenate([chain(n, 0.005, origin=(0, 0, 0.01 * k))
                                                     for k, n in enumerate((40, 24, 64))]), [40, 24, 64])
    stage.Save()
    return str(path)


def _run(path, device, frames, saved=None):
    return simulate_frames(path, device, frames, saved, solver="dftl", damping=0.0, substeps=40)


def simulate_frames(path, device, frames, saved=None, **options):
    """(simulation, its warnings) of ``path`` run to ``frames`` with ``options`` (SimulationOptions),
    continued from the saved state ``saved`` if given."""
    sim = Simulation(read_scene(str(path)), SimulationOptions(device=device, **options), 1)
    warned = []
    sim.on_warning = warned.append
    if saved is not None:
        sim.load_state(saved)
    while sim.frame < frames:
        sim.advance()
        sim.samples()   # checks the energy, as the frame loop does
    return sim, warned


@pytest.mark.parametrize("device", ["cpu", "cpu,cpu"])
def test_resumed_run_warns_as_the_uninterrupted_run(tmp_path, device):
    path = _stage(tmp_path / "in.usda")
    _, want = _run(path, device, 10)
    assert len(want) == 1 and "energy grew" in want[0], want
    frame = int(want[0].split(" at frame ")[1].split(",")[0])
    assert 2 < frame < 9, want
    for resume in (frame - 1, frame + 1):   # saved before the warning, and after it
        first, before = _run(path, device, resume)
        _, after = _run(path, device, 10, first.save_state())
        assert before + after == want if resume < frame else after == want, (resume, before, after, want)
