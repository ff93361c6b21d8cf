"""``render`` and ``info`` on time codes past +-1e15, where a double cannot tell frames apart.

Before, ``simulate`` and ``batch`` refused a stage whose own time range lies past +-1e15
(tests/test_stage_time_limits.py), but ``render`` rendered such a stage's start time (1e20) without
a word, and ``--start 1e16 --end 10000000000000003`` rendered 5 images of which two had one file
name (the first was overwritten); ``--start 1e14 --end 100000000000000.5 --step 0.001`` made 501
images of 33 distinct times. ``info`` showed the range 1e20..1e20+5 as '1e+20..1e+20' without saying
that simulate refuses it, and any range of 7 digits or more rounded: 1000001..1000100 showed as
'1e+06..1e+06'. Now render refuses each with one line (exit 2, nothing written), flags that replace
the stage's time still render, and info shows the time codes exactly and says, as a warning of its
description, why simulate refuses the stage's own frames.
"""

from __future__ import annotations

import json

import pytest
from usd_stages import add_curves, chain, new_stage

from dftl_warp import cli


def _stage(path, start, end):
    stage = new_stage(path, start=start, end=end)
    add_curves(stage, "/World/Hair", chain(4, spacing=0.05, direction=(0.0, -1.0, 0.0)), [4])
    stage.Save()
    return str(path)


def _render(path, out, *flags):
    return cli.main(["render", path, "-o", str(out), "--device", "cpu", "--resolution", "32x18", "--spp", "1", "-q",
                     *flags])


@pytest.mark.parametrize("flags, line", [
    ((), "{path}: the stage's startTimeCode 1e+20 (the time rendered by default) lies past +-1e+15, where a time code "
         "(a double) cannot tell frames apart; give --frame or --start and --end"),
    (("--turntable", "4"), "{path}: the stage's startTimeCode 1e+20 (the time rendered by default) lies past "
                           "+-1e+15, where a time code (a double) cannot tell frames apart; give --frame or --start "
                           "and --end"),
    (("--frame", "1e20"), "--frame 1e+20: past +-1e+15, where a time code (a double) cannot tell frames apart"),
    (("--start", "1e16", "--end", "10000000000000003"),
     "--start 1e+16: past +-1e+15, where a time code (a double) cannot tell frames apart"),
    (("--start", "-1", "--end", "-1000000000000001"),
     "--end -1000000000000001: past +-1e+15, where a time code (a double) cannot tell frames apart"),
    (("--start", "1e14", "--end", "100000000000000.5", "--step", "0.001"),
     "--start 100000000000000 --end 100000000000000.5 --step 0.001: the step is below what a time code (a double) "
     "can tell apart there: frames would repeat"),
])
def test_render_refuses_time_codes_past_the_limit_with_one_line(tmp_path, capsys, flags, line):
    path = _stage(tmp_path / "far.usda", 1e20, 1e20 + 5)
    sheet = "--contact-sheet" if "--start" in flags or "--turntable" in flags else None
    out = tmp_path / "out.png"
    assert _render(path, out, *flags, *([sheet] if sheet else [])) == 2
    err = capsys.readouterr().err
    assert err.splitlines() == ["dftl-warp: error: " + line.format(path=path)], err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["far.usda"]


def test_render_takes_the_limit_and_flags_that_replace_the_stage_s_time(tmp_path, capsys):
    path = _stage(tmp_path / "far.usda", 1e20, 1e20 + 5)
    assert _render(path, tmp_path / "three.png", "--frame", "3") == 0
    assert _render(path, tmp_path / "edge.png", "--frame", "1e15") == 0
    assert _render(path, tmp_path / "f.####.png", "--start", "999999999999998", "--end", "1e15") == 0
    # the curves have no widths: drawn at a default width with a warning (tests/test_render_audit.py), said once a run
    assert capsys.readouterr().err.splitlines() == [f"dftl-warp: warning: {path}: 1 BasisCurves prim (/World/Hair) "
                                                    "without widths or primvars:widths: drawn at a default width, "
                                                    "1/1000 of its bounding-box diagonal"] * 3
    assert sorted(p.name for p in tmp_path.iterdir()) == ["edge.png", "f.1000000000000000.png",
                                                          "f.999999999999998.png", "f.999999999999999.png",
                                                          "far.usda", "three.png"]


def test_info_says_why_simulate_refuses_the_stage_s_range(tmp_path, capsys):
    path = _stage(tmp_path / "far.usda", 1e20, 1e20 + 5)
    warning = (f"{path}: the stage's time range 1e+20..1e+20 (startTimeCode..endTimeCode) reaches past +-1e+15, "
               "where a time code (a double) cannot tell frames apart; give --start and --end (simulate refuses "
               "the stage's own frames)")
    assert cli.main(["info", path]) == 0
    out, err = capsys.readouterr()
    assert err == "" and "  frames      1e+20..1e+20 at 24 per second\n" in out, out
    assert f"  warning     {warning}\n" in out, out
    assert cli.main(["info", path, "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["warnings"] == [warning]


def test_info_shows_every_digit_of_the_time_range(tmp_path, capsys):
    for name, start, end, shown in (("mil", 1000001, 1000100, "1000001..1000100"), ("half", 0.5, 24, "0.5..24"),
                                    ("edge", 999999999999990, 1e15, "999999999999990..1000000000000000")):
        assert cli.main(["info", _stage(tmp_path / f"{name}.usda", start, end)]) == 0
        out = capsys.readouterr().out
        assert f"  frames      {shown} at 24 per second\n" in out and "warning" not in out, out
