"""Zero-length segments (coincident consecutive points) under the solvers that refuse them
(docs/usd.md, "Zero-length segments"): `info` and `simulate` stop with one line naming the file,
the prim, the curve and the segment (0-based within the prim), exit status 2, no traceback, no
output written; the solvers that simulate them (`--solver dftl`) still do."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest
from pxr import Sdf, Vt

from dftl_warp import cli
from dftl_warp.simulation.elastic_setup import zero_length_segment

from usd_stages import add_curves, new_stage

HINT = "the elastic solver needs non-zero rest lengths: remove the coincident points, or use --solver dftl"


def straight(origin, n=4, spacing=0.05):
    return np.asarray(origin, float) + np.arange(n)[:, None] * np.array([spacing, 0.0, 0.0])


def two_prims(path):
    """/World/HairA (fine) and /World/HairB whose curve 1 repeats its point 1 (segment 1 is zero),
    both with widths: the elastic solver by default."""
    stage = new_stage(path, start=1, end=3)
    a = np.concatenate([straight((0, 1, 0)), straight((0, 1, 0.1))])
    add_curves(stage, "/World/HairA", a, [4, 4], widths=1e-4, bending=None)
    b1 = straight((1, 1, 0.1))
    b1[2] = b1[1]
    b = np.concatenate([straight((1, 1, 0)), b1])
    add_curves(stage, "/World/HairB", b, [4, 4], widths=1e-4, bending=None)
    stage.Save()
    return path


def one_line(err: str) -> str:
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in err, err
    return lines[0]


def test_info_refuses_a_zero_length_segment_in_one_line(tmp_path, capsys):
    src = two_prims(tmp_path / "in.usda")
    for extra in ([], ["--json"]):
        assert cli.main(["info", str(src), *extra]) == 2
        captured = capsys.readouterr()
        assert captured.out == ""
        line = one_line(captured.err)
        assert line.startswith(f"dftl-warp: error: {src}: /World/HairB: curve 1, segment 1: points 1 and 2 "
                               "of the curve coincide (a zero-length segment); ")
        assert HINT in line


def test_info_console_script_has_no_traceback(tmp_path):
    src = two_prims(tmp_path / "in.usda")
    run = subprocess.run([sys.executable, "-m", "dftl_warp", "info", str(src)], capture_output=True, text=True,
                         timeout=300)
    assert run.returncode == 2 and run.stdout == ""
    line = one_line(run.stderr)
    assert f"{src}: /World/HairB: curve 1, segment 1:" in line and HINT in line


def test_simulate_refuses_it_before_writing_anything(tmp_path, capsys):
    src = two_prims(tmp_path / "in.usda")
    out = tmp_path / "out" / "o.usda"
    out.parent.mkdir()
    assert cli.main(["simulate", str(src), "-o", str(out), "--quiet", "--device", "cpu"]) == 2
    line = one_line(capsys.readouterr().err)
    assert line.startswith(f"dftl-warp: error: {src}: /World/HairB: curve 1, segment 1: points 1 and 2 ")
    assert HINT in line
    assert list(out.parent.iterdir()) == []


def test_info_of_a_prim_without_widths_runs_dftl_and_describes_it(tmp_path, capsys):
    stage = new_stage(tmp_path / "in.usda", start=1, end=3)
    pts = straight((0, 1, 0))
    pts[1] = pts[0]
    add_curves(stage, "/World/Hair", pts, [4])
    stage.Save()
    assert cli.main(["info", str(tmp_path / "in.usda"), "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["curves"][0]["solver"] == "dftl"


def test_solver_dftl_simulates_what_elastic_refuses(tmp_path, capsys):
    src = two_prims(tmp_path / "in.usda")
    out = tmp_path / "o.usda"
    assert cli.main(["simulate", str(src), "-o", str(out), "--quiet", "--device", "cpu", "--solver", "dftl"]) == 0
    assert out.is_file()


def test_rest_shape_points_are_named_when_they_are_the_zero_length_ones(tmp_path, capsys):
    stage = new_stage(tmp_path / "in.usda", start=1, end=3)
    pts = np.concatenate([straight((0, 1, 0)), straight((0, 1, 0.1))])
    prim = add_curves(stage, "/World/Hair", pts, [4, 4], widths=1e-4, bending=None).GetPrim()
    rest = pts.copy()
    rest[7] = rest[6]
    prim.CreateAttribute("physics:restShapePoints", Sdf.ValueTypeNames.Point3fArray, custom=True).Set(
        Vt.Vec3fArray.FromNumpy(rest.astype(np.float32)))
    stage.Save()
    assert cli.main(["simulate", str(tmp_path / "in.usda"), "-o", str(tmp_path / "o.usda"), "--quiet",
                     "--device", "cpu"]) == 2
    line = one_line(capsys.readouterr().err)
    assert "/World/Hair: curve 1, segment 2: physics:restShapePoints 2 and 3 of the curve coincide" in line
    assert not (tmp_path / "o.usda").exists()


@pytest.mark.parametrize("solver", ["rattle", "reference"])
def test_rattle_and_reference_name_the_prim_curve_and_segment(tmp_path, capsys, solver):
    src = two_prims(tmp_path / "in.usda")
    assert cli.main(["simulate", str(src), "-o", str(tmp_path / "o.usda"), "--quiet", "--device", "cpu",
                     "--solver", solver]) == 2
    line = one_line(capsys.readouterr().err)
    # HairB's curve 1, its points 1 and 2 (strand 3 of the group, after HairA's two)
    assert line == (f"dftl-warp: error: {src}: /World/HairB: curve 1, segment 1: points 1 and 2 of the curve "
                    f"coincide (a zero-length segment); the {solver} solver needs non-zero rest lengths: remove the "
                    "coincident points, or use --solver dftl (or dftl:solver = \"dftl\"), which simulates them")


@pytest.mark.parametrize("solver", ["rattle", "reference"])
def test_rattle_and_reference_model_messages_are_0_based_with_a_hint(solver):
    """Through the Python API (no prim to name) the solvers' own message, 0-based."""
    import dftl_warp as dw

    pts = np.concatenate([straight((0, 1, 0), 3), straight((0.1, 1, 0), 3)])
    pts[4] = pts[3]
    model = dw.Model.from_strands(pts, [3, 3])
    with pytest.raises(ValueError) as info:
        dw.make_solver(model, solver)
    assert str(info.value) == (f"strand 1 of the model, segment 0: points 0 and 1 coincide (a zero-length "
                               f"segment); the {solver} solver needs non-zero rest lengths: remove the "
                               "coincident points, or use --solver dftl, which simulates them")


def test_zero_length_segment_finds_the_first_within_a_curve():
    pts = np.concatenate([straight((0, 0, 0), 3), straight((0.1, 0, 0), 3)])  # curve 1 starts where curve 0 ends
    assert zero_length_segment(pts, [3, 3]) is None
    pts[5] = pts[4]
    assert zero_length_segment(pts, [3, 3]) == (1, 1)
    assert zero_length_segment(pts[:1], [1]) is None
    assert zero_length_segment(np.zeros((4, 3)), [1, 3]) == (1, 0)


def test_a_single_vertex_curve_is_no_zero_length_segment(tmp_path, capsys):
    stage = new_stage(tmp_path / "in.usda", start=1, end=3)
    add_curves(stage, "/World/Hair", np.concatenate([[[0.0, 1.0, 0.0]], straight((0, 1, 0.1))]), [1, 4],
               widths=1e-4, bending=None)
    stage.Save()
    assert cli.main(["info", str(tmp_path / "in.usda"), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["curves"][0]["solver"] == "elastic"
    assert cli.main(["simulate", str(tmp_path / "in.usda"), "-o", str(tmp_path / "o.usda"), "--quiet",
                     "--device", "cpu"]) == 0
