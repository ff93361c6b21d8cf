"""Collider and hair sizes too large for float32.

Before, a Sphere collider of radius 1e30 gave a clean-start line "up to inf m deep" (or, with the
elastic solver, a traceback about coincident points); radius 1e300 and curve widths of 3e38 ran and
exited 0 with numpy overflow warnings only. Now each is one line naming the file, the prim and the
attribute (and index), exit 2, and no output file.
"""

from __future__ import annotations

import re

import pytest
from conftest import chain

from dftl_warp import cli

HEAD = """#usda 1.0
(
    startTimeCode = 1
    endTimeCode = 2
    upAxis = "Y"
    metersPerUnit = 1
)
def Xform "World"
{
    def BasisCurves "Hair"
    {
        uniform token type = "linear"
        int[] curveVertexCounts = [3]
        point3f[] points = [(0, 1, 0), (0, 0.9, 0), (0, 0.8, 0)]
        float[] widths = [WIDTHS] (interpolation = "vertex")
        BINDING
    }
"""


def stage(tmp_path, body: str, widths: str = "0.01, 0.01, 0.01", binding: str = "") -> str:
    path = tmp_path / "in.usda"
    path.write_text(HEAD.replace("WIDTHS", widths).replace("BINDING", binding) + body + "}\n")
    return str(path)


def collider(kind: str, attrs: str, translate: str = "(0, -3, 0)", scale: str = "(1, 1, 1)") -> str:
    return (f'    def {kind} "Ball" (prepend apiSchemas = ["PhysicsCollisionAPI"])\n    {{\n        {attrs}\n'
            f'        double3 xformOp:translate = {translate}\n        float3 xformOp:scale = {scale}\n'
            f'        uniform token[] xformOpOrder = ["xformOp:translate", "xformOp:scale"]\n    }}\n')


def refused(tmp_path, capfd, path: str, pattern: str, *extra: str) -> None:
    out = tmp_path / "out.usda"
    code = cli.main(["simulate", path, "-o", str(out), "--device", "cpu", "-q", *extra])
    err = capfd.readouterr().err
    assert code == 2, err
    assert len(err.splitlines()) == 1 and "Traceback" not in err, err
    assert re.match(rf"^dftl-warp: error: {re.escape(path)}: {pattern}", err.strip()), err
    assert not out.exists()


SQUARE = r"is too large: its square does not fit float32 \(lengths at most 1\.845e\+19\): is the unit right\?$"
FLOAT32 = r"does not fit float32 \(at most 3\.403e\+38\): is the unit right\?$"


@pytest.mark.parametrize("solver", [[], ["--solver", "dftl"]])
def test_a_sphere_radius_whose_square_overflows_float32_is_refused(tmp_path, capfd, solver):
    path = stage(tmp_path, collider("Sphere", "double radius = 1e30"))
    refused(tmp_path, capfd, path, rf"/World/Ball: radius = 1e\+30 {SQUARE}", *solver)


@pytest.mark.parametrize("kind, attrs, shown", [
    ("Sphere", "double radius = 1e300", r"radius = 1e\+300"),
    ("Capsule", "double radius = 0.1\n        double height = 1e300", r"height = 1e\+300"),
    ("Cube", "double size = 1e300", r"size = 1e\+300"),
])
def test_collider_sizes_beyond_float32_are_refused_naming_the_attribute(tmp_path, capfd, kind, attrs, shown):
    refused(tmp_path, capfd, stage(tmp_path, collider(kind, attrs)), rf"/World/Ball: {shown} {FLOAT32}")


def test_a_collider_far_away_or_scaled_past_float32_is_refused(tmp_path, capfd):
    far = stage(tmp_path, collider("Sphere", "double radius = 0.1", translate="(1e300, 0, 0)"))
    refused(tmp_path, capfd, far, r"/World/Ball: translate = \(1e\+300, 0, 0\) \(its position in world space\) "
                                  + FLOAT32)
    scaled = stage(tmp_path, collider("Sphere", "double radius = 1e10", scale="(1e10, 1e10, 1e10)"))
    refused(tmp_path, capfd, scaled, r"/World/Ball: radius = 1e\+20 in world space \(1e\+10 under a scale of "
                                     r"1e\+10\) " + SQUARE)


def test_a_mesh_collider_point_whose_square_overflows_is_refused_naming_its_index(tmp_path, capfd):
    mesh = ('    def Mesh "Ball" (prepend apiSchemas = ["PhysicsCollisionAPI"])\n    {\n'
            '        int[] faceVertexCounts = [3]\n        int[] faceVertexIndices = [0, 1, 2]\n'
            '        point3f[] points = [(0, -1, 0), (1, -1, 0), (0, -1, 1e30)]\n    }\n')
    refused(tmp_path, capfd, stage(tmp_path, mesh), rf"/World/Ball: points\[2\] = \(0, -1, 1e\+30\) {SQUARE}")


def test_a_deforming_mesh_collider_point_too_large_at_a_later_time_is_refused(tmp_path, capfd):
    mesh = ('    def Mesh "Ball" (prepend apiSchemas = ["PhysicsCollisionAPI"])\n    {\n'
            '        int[] faceVertexCounts = [3]\n        int[] faceVertexIndices = [0, 1, 2]\n'
            '        point3f[] points.timeSamples = {1: [(0, -1, 0), (1, -1, 0), (0, -1, 1)], '
            '2: [(0, -1, 0), (1, -1, 0), (0, -1, 1e30)]}\n    }\n')
    refused(tmp_path, capfd, stage(tmp_path, mesh), rf"/World/Ball: points\[2\] = \(0, -1, 1e\+30\) at time 2 {SQUARE}")


def test_curve_widths_whose_square_overflows_float32_are_refused_naming_the_index(tmp_path, capfd):
    path = stage(tmp_path, "", widths="0.01, 3e38, 0.01")
    refused(tmp_path, capfd, path, rf"/World/Hair: widths\[1\] = 3e\+38 {SQUARE}")


def test_hair_moved_past_float32_by_its_transform_is_refused_naming_the_point(tmp_path, capfd):
    """Points 1e300 units away in world space ended in a traceback (SVD did not converge)."""
    path = tmp_path / "in.usda"
    text = HEAD.replace("WIDTHS", "0.01, 0.01, 0.01").replace(
        "BINDING", 'double3 xformOp:translate = (1e300, 0, 0)\n        uniform token[] xformOpOrder = ["xformOp:translate"]')
    path.write_text(text + "}\n")
    refused(tmp_path, capfd, str(path), rf"/World/Hair: points\[0\] = \(1e\+300, 1, 0\) in world space {FLOAT32}")


def test_sizes_that_fit_still_run(tmp_path, capfd):
    """The limit is the float32 arithmetic's, not a guess at sane sizes: a radius of 1e18 runs."""
    path = stage(tmp_path, collider("Sphere", "double radius = 1e18", translate="(0, 1e18, 0)"))
    out = tmp_path / "out.usda"
    assert cli.main(["simulate", path, "-o", str(out), "--device", "cpu", "-q", "--solver", "dftl"]) == 0
    assert out.exists()
