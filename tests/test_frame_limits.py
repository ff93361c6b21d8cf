"""Absurd frame ranges: refused at once with one line, not run for days or written wrong.

Before, ``--end`` had no upper bound: ``simulate --end 1000000000`` on a 10-frame stage set up and
then simulated a billion frames (weeks, even for 3 strands), and frame numbers past 2**53, which a
USD time code (a double) cannot tell apart, wrote 4 frames as 3 time samples at the wrong times
with exit status 0. And the warning that the frames reach past an animated stage's time range was
printed only after the whole run.
"""

from __future__ import annotations

from pathlib import Path

import pytest
from usd_stages import add_curves, animated_xform, chain, new_stage

from dftl_warp import cli
from dftl_warp.batch.checkpoint import run_job
from dftl_warp.batch.jobs import Job
from dftl_warp.errors import UserError
from dftl_warp.options import MAX_FRAME, MAX_FRAMES
from dftl_warp.simulation.simulate import Simulation, simulate_usd


def _stage(path: Path) -> Path:
    stage = new_stage(path)   # 1..10
    animated_xform(stage, "/World/Head", translate={1: (0, 0, 0), 10: (0.5, 0, 0)})
    add_curves(stage, "/World/Head/Hair", chain(4, spacing=0.05), [4])
    stage.Save()
    return path


@pytest.fixture
def no_stepping(monkeypatch):
    """A run that gets as far as simulating a frame fails the test (instead of running for days)."""

    def advance(self):
        raise AssertionError("simulated a frame: the range was not refused")

    monkeypatch.setattr(Simulation, "advance", advance)


def _refused(capsys, tmp_path, *argv) -> str:
    try:
        code = cli.main(["simulate", str(_stage(tmp_path / "in.usda")), "-o", str(tmp_path / "o.usdc"),
                         *map(str, argv)])
    except SystemExit as exc:   # a flag's value refused by argparse
        code = exc.code
    err = capsys.readouterr().err
    assert code == 2 and len(err.splitlines()) == 1 and "Traceback" not in err, err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["in.usda"]   # no output, nothing hidden
    return err


def test_the_largest_frame_numbers_are_distinct_time_codes():
    assert float(MAX_FRAME) != float(MAX_FRAME - 1) and float(-MAX_FRAME) != float(-MAX_FRAME + 1)
    assert float(2 ** 53 + 1) == float(2 ** 53) and MAX_FRAME < 2 ** 53


@pytest.mark.parametrize("flag, value", [("--end", 2 ** 53 + 4), ("--start", 2 ** 53 + 1), ("--start", -10 ** 20)])
def test_frame_numbers_a_time_code_cannot_hold_are_refused(tmp_path, capsys, no_stepping, flag, value):
    other = ["--start", 2 ** 53] if flag == "--end" else ["--end", 2 ** 53 + 3] if value > 0 else []
    err = _refused(capsys, tmp_path, flag, value, *other, "-q")
    assert f"argument {flag}: must be in [-1e+15, 1e+15], got {value}" in err, err
    with pytest.raises(UserError, match=r"must be in \[-1e\+15, 1e\+15\]"):
        simulate_usd(str(tmp_path / "in.usda"), str(tmp_path / "o.usdc"), **{flag[2:]: value})


@pytest.mark.parametrize("argv, frames", [(["--end", 1_000_000_000], 1_000_000_000),
                                          (["--start", -MAX_FRAMES, "--end", 1], MAX_FRAMES + 2)])
def test_a_range_longer_than_a_run_takes_is_refused_before_simulating(tmp_path, capsys, no_stepping, argv, frames):
    err = _refused(capsys, tmp_path, *argv)
    assert err.startswith(f"dftl-warp: error: {tmp_path / 'in.usda'}: ") and f"{frames} frames" in err, err
    assert f"at most {MAX_FRAMES}" in err, err


def test_a_batch_job_with_such_a_range_fails_alone_with_the_line(tmp_path, no_stepping):
    stage = _stage(tmp_path / "in.usda")
    result = run_job(Job(index=1, name="j", input=str(stage), output=str(tmp_path / "o.usdc"),
                         options={"end": 1_000_000_000}), "cpu")
    assert result.status == "failed" and "1000000000 frames" in result.error, result.error


def test_the_longest_range_is_taken(tmp_path):
    from dftl_warp.simulation.settings import resolve_frames
    from dftl_warp.usd.read import read_scene

    scene = read_scene(str(_stage(tmp_path / "in.usda")))
    assert resolve_frames(scene, 5, 4 + MAX_FRAMES) == (5, 4 + MAX_FRAMES)
    with pytest.raises(UserError, match=f"{MAX_FRAMES + 1} frames"):
        resolve_frames(scene, 5, 5 + MAX_FRAMES)


def test_the_range_warning_comes_before_the_run(tmp_path, capsys):
    """A range past the animation is said before the frames run (a long run can be stopped at
    once), once."""
    stage = _stage(tmp_path / "in.usda")
    assert cli.main(["simulate", str(stage), "-o", str(tmp_path / "o.usdc"), "--end", "14"]) == 0
    lines = capsys.readouterr().err.splitlines()
    warned = [k for k, line in enumerate(lines) if "lie partly outside the stage's time range 1..10" in line]
    ran = [k for k, line in enumerate(lines) if line.startswith("dftl-warp: simulating: ")]
    assert len(warned) == 1 and ran and warned[0] < ran[0], lines
