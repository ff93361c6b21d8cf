"""``render`` on gprims too large for its float32 ray tracer.

The renderer squares lengths in float32 (a ray against a sphere: |o - c|^2 - r^2). Before, a
Sphere of radius 1e300 was cast to float32 with numpy's "overflow encountered in cast" warning and
rendered as an infinite sphere; a radius of 1e30, whose square overflows, rendered as whatever inf
arithmetic gave. Now each is refused in one line naming the file, the prim and the attribute (exit
2, no image), as ``simulate`` refuses such colliders."""

from __future__ import annotations

import pytest
from pxr import Gf, UsdGeom
from usd_stages import add_curves, chain, new_stage

from dftl_warp import cli


@pytest.mark.parametrize("kind,attr,value,message", [
    ("Sphere", "radius", 1e300, "/Big: radius = 1e+300 does not fit float32"),
    ("Sphere", "radius", 1e30, "/Big: radius = 1e+30 is too large: its square does not fit float32"),
    ("Cube", "size", 1e200, "/Big: size = 1e+200 does not fit float32"),
    ("Capsule", "height", 1e25, "/Big: height = 1e+25 is too large"),
    ("Sphere", "scale", 1e25, "/Big: radius = 1e+25 in world space is too large"),
    ("Sphere", "translate", 1e25, "/Big: its position = (1e+25, 0, 0) in world space is too large"),
])
def test_a_gprim_too_large_for_float32_is_one_line_and_no_image(tmp_path, capsys, kind, attr, value, message):
    stage = new_stage(tmp_path / "in.usda", start=1, end=1)
    add_curves(stage, "/World/Hair", chain(4, spacing=0.05, direction=(0.0, -1.0, 0.0)), [4], widths=0.001)
    gprim = getattr(UsdGeom, kind).Define(stage, "/Big")
    if attr == "scale":
        gprim.AddScaleOp().Set(Gf.Vec3f(value, value, value))
    elif attr == "translate":
        gprim.AddTranslateOp().Set(Gf.Vec3d(value, 0.0, 0.0))
    else:
        gprim.GetPrim().GetAttribute(attr).Set(value)
    stage.Save()
    out = tmp_path / "out.png"
    assert cli.main(["render", str(tmp_path / "in.usda"), "-o", str(out), "-q"]) == 2
    err = capsys.readouterr().err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("dftl-warp: error: ") and "in.usda: " in lines[0], err
    assert message in lines[0] and "Traceback" not in err and "overflow" not in err, err
    assert not out.exists()


def test_a_gprim_of_ordinary_size_renders(tmp_path):
    stage = new_stage(tmp_path / "in.usda", start=1, end=1)
    add_curves(stage, "/World/Hair", chain(4, spacing=0.05, direction=(0.0, -1.0, 0.0)), [4], widths=0.001)
    UsdGeom.Sphere.Define(stage, "/Ball").GetRadiusAttr().Set(0.05)
    UsdGeom.Cube.Define(stage, "/Box").GetSizeAttr().Set(0.1)
    stage.Save()
    assert cli.main(["render", str(tmp_path / "in.usda"), "-o", str(tmp_path / "out.png"), "-q"]) == 0
    assert (tmp_path / "out.png").exists()
