"""A resumed batch job repeats every warning its run gave before the checkpoint, as the energy warning.

Before, the checkpoint kept the clean start's lines and the energy check's warning, but not the
run's other warnings: a job cut after a collider mesh had outrun its signed distance field, or a
prim had turned faster than its roots' path follows, resumed without a word of either (the
uninterrupted job said both). Now the checkpoint keeps the run's warnings, and the prims already
warned about turning fast: the resumed job says each once, as the uninterrupted one does.
"""

from __future__ import annotations

from test_warnings_one_line import field_box
from batch_stages import stop_after
from usd_stages import add_curves, animated_xform, chain, new_stage

from dftl_warp.batch.checkpoint import CheckpointPolicy, JobFiles, run_job
from dftl_warp.batch.jobs import Job

MOVING = "/World/Kick: its points move up to"
TURNS = "/World/Head/Hair: turns"


def _stage(path):
    """8 frames: a box mesh (with a field) that jumps 0.3 m from frame 1 to 2 and then stays, and a
    head that turns 150 degrees from frame 1 to 2, then 100 more from 6 to 7."""
    stage = new_stage(path, start=1, end=8)
    animated_xform(stage, "/World/Head", rotate_y={1: 0.0, 2: 150.0, 6: 150.0, 7: 250.0})
    add_curves(stage, "/World/Head/Hair", chain(5, 0.02, direction=(0.0, -1.0, 0.0), origin=(0.05, 0.0, 0.0)), [5])
    field_box(stage, "/World/Kick", {1: (1.0, 0.5), 2: (1.0, 0.8), 8: (1.0, 0.8)})
    stage.Save()
    return str(path)


def test_a_resumed_job_repeats_the_run_s_warnings_once(tmp_path):
    stage = _stage(tmp_path / "in.usda")

    def job(output):
        return Job(index=1, name="kick", input=stage, output=str(output), options={"solver": "dftl"})

    whole = run_job(job(tmp_path / "whole.usdc"), "cpu")
    assert whole.status == "done", whole.error
    for piece in (MOVING, TURNS):
        assert sum(f"{stage}: {piece}" in w for w in whole.warnings) == 1, (piece, whole.warnings)

    cut = tmp_path / "cut.usdc"
    first = run_job(job(cut), "cpu", CheckpointPolicy(every_frames=2), stop_after(5))
    assert first.status == "failed" and JobFiles(cut).checkpoint_state.exists(), first.error
    resumed = run_job(job(cut), "cpu", CheckpointPolicy(every_frames=2))
    assert resumed.status == "done" and resumed.resumed_from is not None, resumed.error
    assert 2 < resumed.resumed_from < 6, resumed.resumed_from   # after the first warnings, before the second turn
    assert sorted(resumed.warnings) == sorted(whole.warnings), (resumed.warnings, whole.warnings)
    assert len(resumed.warnings) == len(set(resumed.warnings)), resumed.warnings


def test_a_mesh_outrunning_its_field_all_along_is_warned_about_once_resumed_or_not(tmp_path):
    """The field's 'points move up to X m' warning is given once per run; a resumed run has it from
    its checkpoint and does not add the same warning with the distance of a later frame."""
    path = tmp_path / "fast.usda"
    stage = new_stage(path, start=1, end=8)
    add_curves(stage, "/World/Hair", chain(5, 0.02, direction=(0.0, -1.0, 0.0)), [5])
    # faster every frame: each frame's distance is another
    field_box(stage, "/World/Kick", {frame: (1.0, 0.5 + 0.1 * frame * frame) for frame in range(1, 9)})
    stage.Save()

    def job(output):
        return Job(index=1, name="fast", input=str(path), output=str(output), options={"solver": "dftl"})

    whole = run_job(job(tmp_path / "whole.usdc"), "cpu")
    said = [w for w in whole.warnings if MOVING in w]
    assert whole.status == "done" and len(said) == 1, (whole.error, whole.warnings)
    cut = tmp_path / "cut.usdc"
    assert run_job(job(cut), "cpu", CheckpointPolicy(every_frames=2), stop_after(5)).status == "failed"
    resumed = run_job(job(cut), "cpu", CheckpointPolicy(every_frames=2))
    assert resumed.status == "done" and resumed.resumed_from is not None, resumed.error
    assert [w for w in resumed.warnings if MOVING in w] == said, resumed.warnings
