"""``dftl-warp diff`` compares only frames both caches sample (docs/caches.md, "dftl-warp diff"):
no shared frame is bad input (exit 2, one line naming both files and their frames), frames in one
file only are left out with one warning, and every error line names the files."""

import json

import numpy as np
import pytest
from pxr import Usd, UsdGeom
from usd_stages import add_curves, chain, new_stage

from dftl_warp import cli


def cache(path, frames=(), offset=0.0, strands=2, vertices=4, moved=None):
    """A stage with /World/Hair: default points, plus time samples at ``frames`` (the points moved
    by ``offset`` and by 0.01 per frame; ``moved``: {frame: extra offset})."""
    stage = new_stage(path, end=max(frames, default=10))
    pts = np.concatenate([chain(vertices, 0.1, origin=(0.0, 0.0, 0.2 * s)) for s in range(strands)])
    add_curves(stage, "/World/Hair", pts + offset, [vertices] * strands)
    attr = UsdGeom.BasisCurves(stage.GetPrimAtPath("/World/Hair")).GetPointsAttr()
    for f in frames:
        p = pts + offset + 0.01 * f + (moved or {}).get(f, 0.0)
        attr.Set([tuple(map(float, x)) for x in p], Usd.TimeCode(f))
    stage.Save()
    return str(path)


def diff(capsys, *args):
    code = cli.main(["diff", *map(str, args)])
    out, err = capsys.readouterr()
    return code, out, err


def test_caches_sharing_no_frame_are_bad_input_naming_both_files_and_frames(tmp_path, capsys):
    a = cache(tmp_path / "a.usda", range(1, 11))
    b = cache(tmp_path / "b.usda", range(20, 26))  # equal default points: the old fallback said "equal"
    code, out, err = diff(capsys, a, b)
    assert code == 2 and out == ""
    assert err.count("\n") == 1 and "Traceback" not in err
    assert f"{a} (frames 1..10)" in err and f"{b} (frames 20..25)" in err and "/World/Hair" in err
    assert diff(capsys, a, b, "--json")[0] == 2


def test_a_cache_against_its_unsampled_input_is_bad_input(tmp_path, capsys):
    sim = cache(tmp_path / "sim.usda", range(1, 4))
    src = cache(tmp_path / "src.usda")
    for x, y in ((sim, src), (src, sim)):
        code, out, err = diff(capsys, x, y)
        assert code == 2 and out == "" and err.count("\n") == 1
        assert f"{sim} (frames 1..3)" in err and f"{src} (no time samples)" in err


def test_stages_without_time_samples_compare_their_default_points(tmp_path, capsys):
    a, b = cache(tmp_path / "a.usda"), cache(tmp_path / "b.usda")
    c = cache(tmp_path / "c.usda", offset=0.5)
    code, out, err = diff(capsys, a, b)
    assert code == 0 and "within tolerance 0" in out and err == ""
    code, out, err = diff(capsys, a, c)
    assert code == 1 and "first difference beyond 0 stage units: the default time, /World/Hair" in out
    assert "None" not in out and "inf" not in out
    code, out, err = diff(capsys, a, c, "--json")
    d = json.loads(out)
    assert code == 1 and d["first_beyond"]["time"] is None and d["prims"]["/World/Hair"][0]["time"] is None
    assert d["prims"]["/World/Hair"][0]["max"] == pytest.approx(np.sqrt(3) * 0.5, rel=1e-6)  # offset on x, y, z


def test_partly_overlapping_ranges_compare_the_common_frames_and_warn_once(tmp_path, capsys):
    a = cache(tmp_path / "a.usda", range(1, 11))
    b = cache(tmp_path / "b.usda", range(5, 13))
    code, out, err = diff(capsys, a, b)
    assert code == 0 and "within tolerance 0" in out
    rows = [line.split()[0] for line in out.splitlines()[1:-1]]
    assert rows == [str(f) for f in range(5, 11)]
    assert err.count("\n") == 1 and err.startswith("dftl-warp: warning: ")
    assert f"frames 1..4 only in {a}" in err and f"frames 11..12 only in {b}" in err
    code, out, err = diff(capsys, a, b, "--json")
    d = json.loads(out)
    assert [r["time"] for r in d["prims"]["/World/Hair"]] == [float(f) for f in range(5, 11)]
    assert d["frames_only_in_a"] == [1.0, 2.0, 3.0, 4.0] and d["frames_only_in_b"] == [11.0, 12.0]
    assert err.count("\n") == 1
    # a difference in a common frame is still found
    c = cache(tmp_path / "c.usda", range(5, 13), moved={7: 0.25})
    code, out, err = diff(capsys, a, c, "--tolerance", "0.1")
    assert code == 1 and "frame 7, /World/Hair" in out


def test_point_count_errors_name_both_files_and_the_frame(tmp_path, capsys):
    a = cache(tmp_path / "a.usda", range(1, 4))
    b = cache(tmp_path / "b.usda", range(1, 4), strands=3)
    code, out, err = diff(capsys, a, b)
    assert code == 2 and err.count("\n") == 1
    assert f"/World/Hair: 8 points in {a}, 12 in {b} at frame 1" in err
    a0, b0 = cache(tmp_path / "a0.usda"), cache(tmp_path / "b0.usda", strands=3)
    code, out, err = diff(capsys, a0, b0)
    assert code == 2 and err.count("\n") == 1 and "None" not in err
    assert f"8 points in {a0}, 12 in {b0} at the default time" in err


def test_a_missing_file_or_folder_is_named_as_such(tmp_path, capsys):
    a = cache(tmp_path / "a.usda", range(1, 4))
    for x, y, bad in ((a, tmp_path / "nothing.usdc", tmp_path / "nothing.usdc"),
                      (tmp_path / "gone.usda", a, tmp_path / "gone.usda")):
        code, out, err = diff(capsys, x, y)
        assert code == 2 and out == "" and err == f"dftl-warp: error: {bad}: no such file\n"
    code, out, err = diff(capsys, a, tmp_path)
    assert code == 2 and err == f"dftl-warp: error: {tmp_path}: is a folder, not a USD file\n"
    junk = tmp_path / "junk.usda"
    junk.write_text("not usd\n")
    code, out, err = diff(capsys, a, junk)
    assert code == 2 and err.count("\n") == 1 and f"{junk}: cannot open as a USD stage" in err


def test_json_is_strict_where_points_are_not_finite(tmp_path, capsys):
    """A frame whose points are NaN in one cache differs (exit 1) and its distances are null in
    the JSON (Python's json wrote NaN, which strict parsers refuse)."""
    a = cache(tmp_path / "a.usda", frames=(1, 2))
    b = cache(tmp_path / "b.usda", frames=(1, 2), moved={2: np.nan})
    code, out, _ = diff(capsys, a, b, "--json")
    assert code == 1 and "NaN" not in out
    rows = json.loads(out, parse_constant=lambda c: pytest.fail(f"non-standard JSON constant {c}"))["prims"]
    frame2 = next(r for r in rows["/World/Hair"] if r["time"] == 2.0)
    assert frame2["max"] is None and frame2["max_relative"] is None
    assert json.loads(out)["first_beyond"]["time"] == 2.0


def test_same_points_in_other_curves_are_bad_input(tmp_path, capsys):
    """Equal points split into other curves are another groom: not 'within tolerance'."""
    a = cache(tmp_path / "a.usda", range(1, 3))
    b = cache(tmp_path / "b.usda", range(1, 3))
    stage = Usd.Stage.Open(b)
    UsdGeom.BasisCurves(stage.GetPrimAtPath("/World/Hair")).GetCurveVertexCountsAttr().Set([2, 6])
    stage.Save()
    code, out, err = diff(capsys, a, b)
    assert code == 2 and out == "" and err.count("\n") == 1 and "Traceback" not in err
    assert a in err and b in err and "/World/Hair" in err and "curve 0" in err, err


def test_prims_in_one_file_only_are_warned_about(tmp_path, capsys):
    a = cache(tmp_path / "a.usda", range(1, 3))
    b = cache(tmp_path / "b.usda", range(1, 3))
    stage = Usd.Stage.Open(b)
    add_curves(stage, "/World/Extra", chain(3, 0.1), [3])
    stage.Save()
    code, out, err = diff(capsys, a, b)
    assert code == 0 and "within tolerance 0" in out
    assert err.count("\n") == 1 and "/World/Extra" in err and f"only in {b}" in err, err
