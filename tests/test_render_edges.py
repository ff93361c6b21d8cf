"""``dftl-warp render`` at the edges: curves of one vertex (nothing to draw), a guide binding that names
no guides (``simulate --guides-output binding`` writes them), and an output with two runs of '#'.
What is left out is said once; what cannot be rendered is one line, exit 2, no file."""

import numpy as np
from pxr import Sdf, UsdGeom, Vt

from dftl_warp import cli
from dftl_warp.render import image
from render_util import add_curves, new_stage

STRAND = np.array([[0.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, -2.0, 0.0]])


def render(*args):
    return cli.main(["render", *map(str, args), "--resolution", "24x16", "--spp", "1", "-q"])


def lines(capsys):
    err = capsys.readouterr().err
    assert "Traceback" not in err
    return err.strip().splitlines()


def test_curves_of_one_vertex_only_are_nothing_to_render(tmp_path, capsys):
    """They rendered an empty, transparent image with exit 0 and not a word."""
    src = tmp_path / "points.usda"
    stage = new_stage(src)
    add_curves(stage, "/H", [STRAND[:1], STRAND[1:2]], widths=0.1)
    stage.Save()
    assert render(src, "-o", tmp_path / "out.png") == 2
    (line,) = lines(capsys)
    assert line.startswith("dftl-warp: error: ") and "nothing to render" in line and "2 or more vertices" in line
    assert not (tmp_path / "out.png").exists()


def test_curves_of_one_vertex_among_others_are_named_once(tmp_path, capsys):
    src = tmp_path / "mixed.usda"
    stage = new_stage(src)
    add_curves(stage, "/H", [STRAND, STRAND[:1] + 5.0, STRAND + [1.0, 0.0, 0.0]], widths=0.1)
    stage.Save()
    assert render(src, "-o", tmp_path / "out.png") == 0
    (line,) = lines(capsys)
    assert line == (f"dftl-warp: warning: {src}: /H: 1 of 3 curves have fewer than 2 vertices "
                    "(curveVertexCounts[1] = 1): not drawn (no segment)")
    assert (image.read_png(tmp_path / "out.png")[..., 3] > 0).any()


def test_a_guide_binding_without_its_guides_is_one_line(tmp_path, capsys):
    """A --guides-output binding cache was drawn at rest, with a warning; it is now deformed by its guides
    (tests/test_render_binding.py), and render ids that name no guide prim cannot be: one line, no file."""
    src = tmp_path / "bound.usda"
    stage = new_stage(src)
    hair = add_curves(stage, "/W/Hair", [STRAND, STRAND + [1.0, 0.0, 0.0]], widths=0.1)
    add_curves(stage, "/W/Hair_guides", [STRAND], widths=0.1)
    ids = UsdGeom.PrimvarsAPI(hair.GetPrim()).CreatePrimvar("dftl:guideIds", Sdf.ValueTypeNames.IntArray,
                                                            UsdGeom.Tokens.uniform, 1)
    ids.Set(Vt.IntArray([0, 0]))
    stage.Save()
    assert render(src, "-o", tmp_path / "out.png") == 2
    assert lines(capsys) == [f"dftl-warp: error: {src}: /W/Hair: primvars:dftl:guideIds without rel dftl:guides: a "
                             "guide binding must name its guide prims"]
    assert not (tmp_path / "out.png").exists()
    # a plain groom says nothing
    plain = tmp_path / "plain.usda"
    stage = new_stage(plain)
    add_curves(stage, "/W/Hair", [STRAND], widths=0.1)
    stage.Save()
    assert render(plain, "-o", tmp_path / "plain.png") == 0
    assert lines(capsys) == []


def test_a_pattern_with_two_runs_of_hashes_is_refused(tmp_path, capsys):
    """Only the first run was numbered: frames went to a.1.b.##.png, a.2.b.##.png."""
    src = tmp_path / "groom.usda"
    stage = new_stage(src)
    add_curves(stage, "/H", [STRAND], widths=0.1)
    stage.Save()
    for extra in (["--start", "1", "--end", "2"], ["--frame", "1"]):
        assert render(src, *extra, "-o", tmp_path / "seq" / "a.#.b.##.png") == 2
        (line,) = lines(capsys)
        assert line.startswith("dftl-warp: error: -o ") and "more than one run of '#'" in line
    assert not (tmp_path / "seq").exists()
