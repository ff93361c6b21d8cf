"""dftl-warp import: a unit or a head that does not fit the hair is one warning, measured.

A groom's unit only sets ``metersPerUnit`` (points are written as read), so a wrong ``--units`` or
a format default that does not fit the file (the Sintel ``.tfx`` is in centimetres, the default
is metres) gives hair tens of metres long that the simulator then calls unstable; a head mesh
exported in another unit lies far from the roots and never collides. Both were accepted without
a word. The median strand length in the warning is the strands' own (their polylines)."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from test_importers import run_cli, write_ply

from dftl_warp.importers import GroomImportWarning
from dftl_warp.importers.convert import import_groom

SEGMENT = 10.0   # units (mm by the PLY default): strands of 9 segments are 9 cm long


def groom(tmp_path):
    """A 3 x 3 patch of straight strands hanging from the top of a 100-unit cube head."""
    roots = np.array([[x, 50.0, z] for x in (-20.0, 0.0, 20.0) for z in (-20.0, 0.0, 20.0)])
    pts = np.concatenate([r + np.arange(10)[:, None] * SEGMENT * np.array([0.3, 0.0, 0.954]) for r in roots])
    return write_ply(tmp_path / "g.ply", pts, [10] * len(roots)), 9 * SEGMENT * np.hypot(0.3, 0.954)


def cube(path, half):
    path.write_text("".join(f"v {x} {y} {z}\n" for x in (-half, half) for y in (-half, half) for z in (-half, half))
                    + "f 1 2 4 3\nf 5 7 8 6\nf 1 5 6 2\nf 3 4 8 7\nf 1 3 7 5\nf 2 6 8 4\n")
    return path


def notes(src, out, **options):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        import_groom(src, out, **options)
    assert all(issubclass(w.category, GroomImportWarning) for w in caught)
    return [str(w.message) for w in caught if "median length" in str(w.message) or "head mesh" in str(w.message)]


def test_right_units_and_head_say_nothing(tmp_path):
    src, _ = groom(tmp_path)
    assert notes(src, tmp_path / "a.usda") == []                                  # mm, the PLY default
    assert notes(src, tmp_path / "b.usda", units="cm") == []                      # 90 cm: long hair
    assert notes(src, tmp_path / "c.usda", head=cube(tmp_path / "head.obj", 50.0)) == []


@pytest.mark.parametrize("units, mpu, advice", [("m", 1.0, "mm"), ("um", 1e-6, "mm"), (0.5, 0.5, "mm")])
def test_a_unit_that_makes_no_hair_is_named_with_the_one_that_does(tmp_path, units, mpu, advice):
    src, length = groom(tmp_path)
    found = notes(src, tmp_path / "g.usda", units=units)
    assert len(found) == 1, found
    line = found[0]
    assert line.startswith(f"{src}: the strands' median length is ") and "(--units)" in line, line
    median = float(line.split("median length is ")[1].split(" units")[0])
    assert median == pytest.approx(length, rel=1e-3)
    assert float(line.split(" units = ")[1].split(" m at")[0]) == pytest.approx(length * mpu, rel=1e-3)
    assert line.endswith(f"in {advice} it is {length * 1e-3:.3g} m: give --units {advice}"), line
    assert (tmp_path / "g.usda").exists()                       # a warning: the groom is written


def test_the_format_default_is_questioned_too_from_the_command(tmp_path, capsys):
    tiny = write_ply(tmp_path / "tiny.ply", np.array([[0, 0, 0], [0, 0, 0.75], [0, 0, 1.5]]), [3])
    code, _, err = run_cli(["import", str(tiny), "-o", str(tmp_path / "t.usda")], capsys)
    lines = [w for w in err.splitlines() if "median length" in w]
    assert code == 0 and len(lines) == 1, err
    assert "= 0.0015 m at 0.001 m per unit (the format's default unit)" in lines[0]
    assert lines[0].startswith("dftl-warp: warning: ") and lines[0].endswith("give --units cm"), lines[0]


def test_a_head_in_other_units_than_the_hair_is_named(tmp_path, capsys):
    """The cube head exported in metres (0.1 across) with hair in millimetres: every root is
    outside its bounds; the warning names the head file and the sizes measured."""
    src, _ = groom(tmp_path)
    head = cube(tmp_path / "head_m.obj", 0.05)
    out = tmp_path / "g.usda"
    code, _, err = run_cli(["import", str(src), "-o", str(out), "--head", str(head)], capsys)
    lines = [w for w in err.splitlines() if "head mesh" in w]
    assert code == 0 and len(lines) == 1 and out.exists(), err
    expected = (f"dftl-warp: warning: {head}: 9 of 9 hair roots lie outside the head mesh's bounds "
                f"(head {np.sqrt(3) * 0.1:.3g} units across, roots {np.hypot(40, 40):.3g} across")
    assert lines[0].startswith(expected), lines[0]
    # --up-axis X turns the hair and the head alike before they are compared
    assert notes(src, tmp_path / "r.usda", head=cube(tmp_path / "head.obj", 50.0), up_axis="X") == []


def test_strands_far_shorter_than_the_rest_are_named(tmp_path):
    """A strand of 1e-3 the others' length (an artefact: a public TressFX groom has one of 7.5 um
    with 32 points) is one warning naming the shortest; the groom is written as read."""
    roots = np.array([[x, 50.0, 0.0] for x in (-20.0, 0.0, 20.0, 40.0)])
    pts = [r + np.arange(10)[:, None] * SEGMENT * np.array([0.0, -1.0, 0.0]) for r in roots[:3]]
    pts.append(roots[3] + np.arange(10)[:, None] * 1e-3 * SEGMENT * np.array([0.0, -1.0, 0.0]))
    src = write_ply(tmp_path / "g.ply", np.concatenate(pts), [10] * 4)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        import_groom(src, tmp_path / "g.usda")
    found = [str(w.message) for w in caught if "shorter than" in str(w.message)]
    assert len(found) == 1, [str(w.message) for w in caught]
    assert found[0].startswith(f"{src}: 1 of 4 strands are shorter than 1% of the median strand (90 units)")
    assert "strand 3, is 0.09 units long with 10 points" in found[0], found[0]
    assert (tmp_path / "g.usda").exists()
    src, _ = groom(tmp_path)       # strands of one length: nothing to say
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        import_groom(src, tmp_path / "h.usda")
    assert not [w for w in caught if "shorter than" in str(w.message)]
