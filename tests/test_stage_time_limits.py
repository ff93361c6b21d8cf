"""A stage whose own time range lies past +-1e15 is refused before any work, as --start/--end are.

Before, ``--start``/``--end`` beyond 1e15 were refused (tests/test_frame_limits.py), but a stage
authoring ``startTimeCode = 1e20``, ``endTimeCode = 1e20 + 5`` ran: a double cannot tell those
frames apart (both read 1e20), so it simulated and wrote one frame at the wrong time, exit 0. Now
the range is one line naming the file and the time codes, exit 2, nothing written, nothing
simulated; the batch job fails alone with the same line. Given --start and --end, the stage's range
is not used and the run goes on.
"""

from __future__ import annotations

import pytest
from test_frame_limits import no_stepping  # noqa: F401  (a fixture)
from usd_stages import add_curves, chain, new_stage

from dftl_warp import cli
from dftl_warp.batch.checkpoint import run_job
from dftl_warp.batch.jobs import Job


def _stage(path, start, end):
    stage = new_stage(path, start=start, end=end)
    add_curves(stage, "/World/Hair", chain(4, spacing=0.05, direction=(0.0, -1.0, 0.0)), [4])
    stage.Save()
    return str(path)


@pytest.mark.parametrize("start, end, shown", [(1e20, 1e20 + 5, "1e+20..1e+20"), (-1e20, -1e20 + 5, "-1e+20..-1e+20"),
                                               (1e15, 1e15 + 3, "1000000000000000..1000000000000003"),
                                               (-1e15 - 8, 0, "-1000000000000008..0")])
def test_a_stage_range_past_the_limit_is_refused_before_any_work(tmp_path, capsys, no_stepping,  # noqa: F811
                                                                 start, end, shown):
    path = _stage(tmp_path / "in.usda", start, end)
    assert cli.main(["simulate", path, "-o", str(tmp_path / "o.usdc")]) == 2
    err = capsys.readouterr().err
    assert err.splitlines() == [f"dftl-warp: error: {path}: the stage's time range {shown} "
                                f"(startTimeCode..endTimeCode) reaches past +-1e+15, where a time code (a double) "
                                f"cannot tell frames apart; give --start and --end"], err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["in.usda"]
    result = run_job(Job(index=1, name="j", input=path, output=str(tmp_path / "j.usdc"), options={}), "cpu")
    assert result.status == "failed" and f"time range {shown} " in result.error, result.error
    assert sorted(p.name for p in tmp_path.iterdir()) == ["in.usda"]


def test_the_limit_itself_and_given_frames_run(tmp_path, capsys):
    """Frame 1e15 is a time code of its own (the flags' limit too); and the flags replace the range."""
    path = _stage(tmp_path / "edge.usda", 1e15 - 1, 1e15)
    assert cli.main(["simulate", path, "-o", str(tmp_path / "edge.usdc"), "-q"]) == 0
    assert "2 frames (999999999999999..1000000000000000)" in capsys.readouterr().out
    path = _stage(tmp_path / "far.usda", 1e20, 1e20 + 5)
    assert cli.main(["simulate", path, "-o", str(tmp_path / "far.usdc"), "--start", "1", "--end", "3", "-q"]) == 0
    assert "3 frames (1..3)" in capsys.readouterr().out
