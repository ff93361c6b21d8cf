"""A resumed batch job does not redo the preroll: the checkpoint's state replaces it.

Before, a job resumed from its checkpoint first ran the whole clean start again, the ``preroll``
settling included (minutes for a large groom with ``preroll = 1``), then loaded the checkpoint
over the result. The checkpoint holds every State array but not the elastic solver's rest shape,
which the clean start sets where it moves hair out of a collider: a resumed run still moves the
hair out (cheap, and the rest shape follows exactly as in the uninterrupted run), but does not
step the preroll; its output equals the uninterrupted run's bit for bit, and it repeats the clean
start's lines of the run it continues.
"""

from __future__ import annotations

import numpy as np
import pytest
from pxr import Gf, UsdGeom, UsdPhysics

from batch_stages import hidden_files, layer_content, stop_after
from usd_stages import add_curves, animated_xform, chain
from usd_stages import new_stage
from dftl_warp.batch.checkpoint import CheckpointPolicy, JobFiles, run_job
from dftl_warp.batch.jobs import Job
from dftl_warp.solvers.base import Solver
from dftl_warp.solvers.dftl import DFTLSolver

RADIUS = 0.025   # hair radius, cm
END = 10


def _stage(path, ball=True):
    """A head (cm) that moves and turns; a ball under it that some hair starts inside: DFTL chains
    (``dftl:bending = false``) and elastic rods (widths, bending), one of each through the ball."""
    stage = new_stage(path, meters_per_unit=0.01, start=1, end=END)
    animated_xform(stage, "/World/Head", translate={1: (0, 0, 0), END: (6, 0, 0)}, rotate_y={1: 0.0, END: 60.0})
    if ball:
        sphere = UsdGeom.Sphere.Define(stage, "/World/Head/Ball")
        sphere.CreateRadiusAttr(2.0)
        UsdGeom.XformCommonAPI(sphere).SetTranslate(Gf.Vec3d(0.0, -6.0, 0.0))
        UsdPhysics.CollisionAPI.Apply(sphere.GetPrim())
    down = (0.0, -1.0, 0.0)
    add_curves(stage, "/World/Head/Chains", np.concatenate([chain(9, 0.8, down, (x, -0.4, 0.3)) for x in (0.8, 3.0)]),
               [9, 9], widths=2 * RADIUS)
    add_curves(stage, "/World/Head/Rods", np.concatenate([chain(9, 0.8, down, (x, -0.4, -0.3)) for x in (1.2, -3.0)]),
               [9, 9], widths=2 * RADIUS, bending=True)
    stage.GetRootLayer().Save()
    return path


@pytest.fixture
def frames_stepped(monkeypatch):
    """How many frames (``advance`` calls) every solver stepped: the preroll's and the shot's."""
    count = []
    for cls in (Solver, DFTLSolver):
        original = cls.advance

        def advance(self, *args, _original=original, **kwargs):
            count.append(type(self).__name__)
            return _original(self, *args, **kwargs)

        monkeypatch.setattr(cls, "advance", advance)
    return count


def _job(stage, output, **options) -> Job:
    return Job(index=1, name="ball", input=str(stage), output=str(output), options=options)


def _interrupted(stage, cut, options):
    """Run the job into ``cut`` until frame 7 is written, with a checkpoint at frame 7's state."""
    first = run_job(_job(stage, cut, **options), "cpu", CheckpointPolicy(every_frames=3), stop_after(7))
    assert first.status == "failed" and JobFiles(cut).checkpoint_state.exists()


def _reference(tmp_path, stage, options, frames_stepped):
    """(uninterrupted output, its clean start's lines, preroll frames stepped), and the path of the other."""
    (tmp_path / "whole").mkdir()
    (tmp_path / "cut").mkdir()
    whole, cut = tmp_path / "whole" / "ball.usdc", tmp_path / "cut" / "ball.usdc"
    reference = run_job(_job(stage, whole, **options), "cpu")
    assert reference.status == "done", reference.error
    prerolled = [n for n in reference.notes + reference.warnings if n.startswith("preroll: ")]
    preroll_frames = len(frames_stepped) - 2 * (END - 1)   # two groups step every frame of the shot
    assert preroll_frames == sum(int(n.split(" frames)")[0].split("(")[-1]) for n in prerolled)
    del frames_stepped[:]
    return whole, reference.notes + reference.warnings, preroll_frames, cut


@pytest.mark.parametrize("ball, preroll", [(True, 0.0), (True, 0.1), (False, 0.1)])
def test_resumed_job_skips_the_preroll_and_writes_the_same_output(tmp_path, frames_stepped, ball, preroll):
    stage = _stage(tmp_path / "ball.usda", ball)
    options = dict(substeps=4, preroll=preroll)
    whole, notes, preroll_frames, cut = _reference(tmp_path, stage, options, frames_stepped)
    # both groups start inside the ball; the elastic one rests where it was moved out
    assert sum("started inside a collider" in n for n in notes) == (2 if ball else 0), notes
    assert any("elastic strand rests where it was moved out" in n for n in notes) == ball, notes
    assert len([n for n in notes if n.startswith("preroll: ")]) == (2 if preroll else 0), notes
    assert (preroll_frames > 0) == (preroll > 0)
    _interrupted(stage, cut, options)
    del frames_stepped[:]
    resumed = run_job(_job(stage, cut, **options), "cpu", CheckpointPolicy(every_frames=0, every_seconds=0))
    assert resumed.status == "done" and resumed.resumed_from == 6, (resumed.error, resumed.notes)
    # the shot's frames after the checkpoint's (frame 7) only, in both groups: no preroll
    assert len(frames_stepped) == 2 * (END - 7), frames_stepped
    assert layer_content(cut) == layer_content(whole)
    # the clean start's lines of the run it continues, the preroll's included
    assert [n for n in resumed.notes + resumed.warnings if "resum" not in n] == notes
    assert hidden_files(tmp_path / "cut") == []


def test_a_checkpoint_found_unusable_once_set_up_starts_over_with_the_preroll(tmp_path, frames_stepped):
    """A checkpoint of these settings whose state layout is not this run's (here: its recorded
    signature changed) is found out only once the simulation is set up without its preroll: the
    job then starts over from a clean start with the preroll, as an uninterrupted run."""
    stage = _stage(tmp_path / "ball.usda")
    options = dict(substeps=4, preroll=0.1)
    whole, notes, preroll_frames, cut = _reference(tmp_path, stage, options, frames_stepped)
    _interrupted(stage, cut, options)
    path = JobFiles(cut).checkpoint_state
    with np.load(path, allow_pickle=False) as data:
        state = {k: data[k] for k in data.files}
    state["signature"] = np.array("another device")
    with open(path, "wb") as f:
        np.savez(f, **state)
    del frames_stepped[:]
    again = run_job(_job(stage, cut, **options), "cpu")
    assert again.status == "done" and again.resumed_from is None, (again.error, again.notes)
    assert "checkpoint was taken on another kind of device; starting over" in again.notes
    assert len(frames_stepped) == preroll_frames + 2 * (END - 1)
    assert layer_content(cut) == layer_content(whole)
    assert [n for n in again.notes + again.warnings if "starting over" not in n] == notes
