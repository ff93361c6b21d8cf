"""The USD reader's bad-input contract, case by case from the CLI audit (/tmp/audit_cli/report.md):
one line naming the file, the prim and the attribute, exit 2, no traceback and no output for bad
input; a warning (one line, naming the prim) for anything approximated or skipped.

Each test writes a small .usda (two strands of 4 vertices, frames 1..3, metres) and reads it with
:func:`~dftl_warp.usd.read.read_scene`, or runs ``dftl-warp simulate`` / ``info`` in-process
(``cli.main``) where the exit code and the printed line are the point."""

from __future__ import annotations

import os

import pytest
from usd_stages import USDA_HEAD

from dftl_warp import cli
from dftl_warp.errors import UserError
from dftl_warp.usd.read import read_scene
from dftl_warp.usd.stage import tf_message

HAIR = """
    def BasisCurves "Hair"
    {{
        int[] curveVertexCounts = {counts}
        point3f[] points = [(0, 0, 0), (0, -0.1, 0), (0, -0.2, 0), (0, -0.3, 0), (0.1, 0, 0), (0.1, -0.1, 0), (0.1, -0.2, 0), (0.1, -0.3, 0)]
        uniform token type = "linear"
        float[] widths = [0.01] (interpolation = "constant")
{hair}
    }}
"""


def stage_text(extra: str = "", *, counts: str = "[4, 4]", hair: str = "", head: str = USDA_HEAD) -> str:
    return f'{head}\ndef Xform "World"\n{{{HAIR.format(counts=counts, hair=hair)}{extra}\n}}\n'


def collider(kind: str, name: str, body: str) -> str:
    return f"""
    def {kind} "{name}" (
        prepend apiSchemas = ["PhysicsCollisionAPI"]
    )
    {{
        {body}
    }}
"""


def write(tmp_path, text, name="in.usda"):
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


def refused(tmp_path, text) -> str:
    """The one-line UserError the reader raises for ``text``, without the file name."""
    path = write(tmp_path, text)
    with pytest.raises(UserError) as err:
        read_scene(path)
    message = str(err.value)
    assert "\n" not in message
    assert message.startswith(f"{path}: "), message
    return message[len(f"{path}: "):]


def warnings_of(tmp_path, text) -> list[str]:
    path = write(tmp_path, text)
    prefix = f"{path}: "
    return [w[len(prefix):] if w.startswith(prefix) else w for w in read_scene(path).warnings]


def run(capsys, tmp_path, command, path, *extra):
    """``dftl-warp COMMAND PATH ...``: (exit code, stdout, stderr); simulate writes out.usda."""
    argv = [command, str(path), *extra]
    if command == "simulate":
        argv += ["-o", str(tmp_path / "out.usda"), "--quiet"]
    code = cli.main(argv)
    out, err = capsys.readouterr()
    return code, out, err


def assert_one_line_error(capsys, tmp_path, text, *pieces, command="simulate"):
    """``text`` (or a file already written) refused by ``command``: exit 2, one line with ``pieces``."""
    path = text if isinstance(text, os.PathLike) else write(tmp_path, text)
    before = set(os.listdir(tmp_path))
    code, _, err = run(capsys, tmp_path, command, path)
    assert code == 2, err
    assert "Traceback" not in err
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith(f"dftl-warp: error: {path}: "), lines[0]
    for piece in pieces:
        assert piece in lines[0], (piece, lines[0])
    assert set(os.listdir(tmp_path)) == before, "output left behind"
    return lines[0]


# -- #1: a byte that is not UTF-8 --------------------------------------------------------------------


def write_latin1(tmp_path, text, name="in.usda"):
    path = tmp_path / name
    path.write_bytes(text.encode("latin-1"))
    return path


def test_a_latin1_byte_is_one_line_cannot_open_not_a_traceback(capsys, tmp_path):
    path = write_latin1(tmp_path, stage_text().replace('def Xform "World"', '# caf\u00e9\ndef Xform "World"', 1))
    line = assert_one_line_error(capsys, tmp_path, path, "cannot open as a USD stage: not valid UTF-8 "
                                                         "(byte 0xe9 at line 9, column 6)")
    assert line.endswith("USD text files are UTF-8 (save the file as UTF-8)")


def test_a_latin1_byte_in_info_and_in_a_sublayer(capsys, tmp_path):
    bad = write_latin1(tmp_path, stage_text(hair='        custom string note = "caf\u00e9"'), "bad.usda")
    code, _, err = run(capsys, tmp_path, "info", bad)
    assert code == 2 and "Traceback" not in err and len(err.strip().splitlines()) == 1, err
    assert "not valid UTF-8 (byte 0xe9 at line" in err
    # a sublayer that does not open is a USD warning: its message (with the byte) comes back as one line
    top = write(tmp_path, USDA_HEAD.replace("(\n", "(\n    subLayers = [@bad.usda@]\n", 1)
                + 'def BasisCurves "Other"\n{\n    int[] curveVertexCounts = [2]\n'
                  '    point3f[] points = [(0, 0, 0), (0, -0.1, 0)]\n    uniform token type = "linear"\n}\n', "top.usda")
    scene = read_scene(top)
    assert any("Could not load sublayer" in w and "bad.usda" in w for w in scene.warnings), scene.warnings


def test_tf_message_survives_bytes_that_are_not_utf8():
    class Undecodable:
        def __str__(self):
            raise UnicodeDecodeError("utf-8", b"bad \xe9 byte", 4, 5, "invalid continuation byte")

    assert tf_message(Exception(Undecodable())) == "bad \ufffd byte"


# -- #2, #4: collider sizes of zero or of the wrong type -------------------------------------------------


@pytest.mark.parametrize("kind, body, message", [
    ("Sphere", "double radius = 0", "/World/C: radius = 0: must be a finite number > 0"),
    ("Sphere", "double radius.timeSamples = {1: 0}", "/World/C: radius = 0: must be a finite number > 0"),
    ("Capsule", "double radius = 0", "/World/C: radius = 0: must be a finite number > 0"),
    ("Cube", "double size = 0", "/World/C: size = 0: must be a finite number > 0"),
    ("Sphere", 'string radius = "big"', "/World/C: radius = 'big': expected a number"),
    ("Capsule", 'string radius = "x"', "/World/C: radius = 'x': expected a number"),
    ("Capsule", 'string height = "tall"', "/World/C: height = 'tall': expected a number"),
    ("Cube", 'string size = "x"', "/World/C: size = 'x': expected a number"),
])
def test_a_collider_size_of_zero_or_not_a_number_is_refused(tmp_path, kind, body, message):
    assert refused(tmp_path, stage_text(collider(kind, "C", body))) == message


def test_a_zero_radius_through_the_cli_is_one_line(capsys, tmp_path):
    assert_one_line_error(capsys, tmp_path, stage_text(collider("Sphere", "Head", "double radius = 0")),
                          "/World/Head: radius = 0: must be a finite number > 0")
    assert_one_line_error(capsys, tmp_path, stage_text(collider("Cube", "Box", "double size = 0")),
                          "/World/Box: size = 0", command="info")


@pytest.mark.parametrize("body, message", [
    ('string physics:gravityDirection = "down"', "/World/Phys: physics:gravityDirection = 'down': expected 3 numbers"),
    ('string physics:gravityMagnitude = "earth"', "/World/Phys: physics:gravityMagnitude = 'earth': expected a number"),
    # #17: plain values, not np.float64(nan)
    ("vector3f physics:gravityDirection = (nan, -1, 0)", "/World/Phys: gravityDirection (nan, -1, 0) is not finite"),
])
def test_gravity_of_the_wrong_type_is_refused_in_plain_words(tmp_path, body, message):
    assert refused(tmp_path, stage_text(f'\n    def PhysicsScene "Phys"\n    {{\n        {body}\n    }}\n')) == message


# -- #3: a signed distance field cell too small ---------------------------------------------------------


SDF_MESH = collider("Mesh", "Col", """int[] faceVertexCounts = [3]
        int[] faceVertexIndices = [0, 1, 2]
        point3f[] points = [(-1, -2, -1), (1, -2, -1), (1, -2, 1)]
        custom bool dftl:collisionSdf = true
        custom float dftl:collisionSdfCellSize = 1e-4""")


@pytest.mark.parametrize("command", ["simulate", "info"])
def test_a_tiny_sdf_cell_is_one_line_naming_the_attribute(capsys, tmp_path, command):
    line = assert_one_line_error(capsys, tmp_path, stage_text(SDF_MESH), "/World/Col: dftl:collisionSdfCellSize = 0.0001",
                                 "(at most 67108864): author a larger dftl:collisionSdfCellSize", command=command)
    assert "larger sdf_cell" not in line and "Traceback" not in line


# -- #6: collider meshes without area -----------------------------------------------------------------


def mesh(counts, indices, points="[(-1, -2, -1), (1, -2, -1), (1, -2, 1), (-1, -2, 1)]"):
    return collider("Mesh", "Col", f"int[] faceVertexCounts = {counts}\n        int[] faceVertexIndices = {indices}\n"
                                   f"        point3f[] points = {points}")


@pytest.mark.parametrize("body", [
    mesh("[3]", "[0, 0, 0]"),
    mesh("[3]", "[0, 1, 2]", "[(5, 5, 5), (6, 5, 5), (7, 5, 5)]"),
    mesh("[3, 4]", "[0, 0, 1, 0, 1, 1, 0]"),
])
def test_a_collider_mesh_without_area_is_refused(tmp_path, body):
    assert refused(tmp_path, stage_text(body)).startswith("/World/Col: no face of non-zero area (")


def test_degenerate_faces_of_a_collider_mesh_are_warned_about_once(tmp_path):
    body = mesh("[3, 3, 3, 4]", "[0, 1, 2, 0, 0, 0, 1, 1, 2, 0, 1, 2, 3]")
    warned = [w for w in warnings_of(tmp_path, stage_text(body)) if "zero area" in w]
    assert warned == ["/World/Col: 2 of 4 faces have zero area (faces 1, 2: collinear or coincident corners): "
                      "they stop no hair and can mislead which side is inside; remove them"]
    holes = mesh("[3, 3, 3]", "[0, 1, 2, 0, 0, 0, 1, 1, 2]").replace("point3f", "int[] holeIndices = [1]\n        point3f")
    warned = [w for w in warnings_of(tmp_path, stage_text(holes)) if "zero area" in w]
    assert warned == ["/World/Col: 1 of 2 faces has zero area (face 2: collinear or coincident corners): "
                      "it stops no hair and can mislead which side is inside; remove it"]


# -- #7: a Capsule's axis --------------------------------------------------------------------------------


@pytest.mark.parametrize("axis", ["W", "x"])
def test_a_capsule_axis_that_is_not_x_y_or_z_is_refused(tmp_path, axis):
    body = f'double radius = 0.05\n        double height = 0.1\n        uniform token axis = "{axis}"'
    assert refused(tmp_path, stage_text(collider("Capsule", "Cap", body))) == (
        f"/World/Cap: axis = '{axis}': must be \"X\", \"Y\" or \"Z\" (UsdGeomCapsule's axis tokens)")


# -- #8: physics material bindings to nothing ---------------------------------------------------------------


@pytest.mark.parametrize("target, problem", [
    ("/World/Looks/Nope", "no such prim"),
    ("/World/Head", "a Sphere prim, not a Material"),
])
def test_a_physics_binding_to_no_material_is_warned_about(tmp_path, target, problem):
    head = collider("Sphere", "Head", "double radius = 0.05\n        double3 xformOp:translate = (0, 0.2, 0)\n"
                                      '        uniform token[] xformOpOrder = ["xformOp:translate"]')
    text = stage_text(head, hair=f"        rel material:binding:physics = <{target}>")
    text = text.replace('def BasisCurves "Hair"', 'def BasisCurves "Hair" (\n        prepend apiSchemas = '
                                                  '["MaterialBindingAPI"]\n    )', 1)
    warned = [w for w in warnings_of(tmp_path, text) if "material:binding" in w]
    assert warned == [f"/World/Hair: material:binding:physics -> {target}: {problem}: the binding is skipped "
                      f"(the hair has human hair's material)"]


def test_a_collider_binding_to_no_material_is_warned_about(tmp_path):
    head = collider("Sphere", "Head", "double radius = 0.05\n        rel material:binding:physics = </World/Nope>")
    warned = [w for w in warnings_of(tmp_path, stage_text(head)) if "material:binding" in w]
    assert warned == ["/World/Head: material:binding:physics -> /World/Nope: no such prim: the binding is skipped "
                      "(the collider's friction is dftl-warp's default)"]


# -- #9: physics:collisionEnabled -------------------------------------------------------------------------


def test_a_time_sampled_collision_enabled_is_read_at_the_start_and_warned_about(tmp_path):
    head = collider("Sphere", "Head", "double radius = 0.05\n        bool physics:collisionEnabled.timeSamples = "
                                      "{1: false, 2: true}")
    path = write(tmp_path, stage_text(head))
    scene = read_scene(path)
    assert scene.colliders == []   # off at the start frame: off for the shot
    assert f"{path}: /World/Head: physics:collisionEnabled is time-sampled and changes over time: the value at " \
           f"time 1 (false) holds for the whole shot (a collider cannot be switched on or off during it)" in scene.warnings


def test_a_collision_enabled_that_is_not_a_bool_is_refused(tmp_path):
    head = collider("Sphere", "Head", 'double radius = 0.05\n        custom string physics:collisionEnabled = "no"')
    assert refused(tmp_path, stage_text(head)) == \
        "/World/Head: physics:collisionEnabled = 'no': expected a bool (true or false)"


# -- #12: curves of one vertex ----------------------------------------------------------------------------


def test_curves_of_a_single_vertex_are_warned_about(tmp_path):
    warned = [w for w in warnings_of(tmp_path, stage_text(counts="[1, 4, 3]")) if "single vertex" in w]
    assert warned == ["/World/Hair: 1 of 3 curves has a single vertex (curve 0: curveVertexCounts = 1): no segment "
                      "to simulate; it stays a root that follows the prim's transform (and is not drawn)"]
    warned = [w for w in warnings_of(tmp_path, stage_text(counts="[1, 1, 5, 1]")) if "single vertex" in w]
    assert warned and warned[0].startswith("/World/Hair: 3 of 4 curves have a single vertex (curves 0, 1, 3: ")


def test_a_single_vertex_curve_simulates_with_the_warning(capsys, tmp_path):
    code, _, err = run(capsys, tmp_path, "simulate", write(tmp_path, stage_text(counts="[1, 4, 3]")))
    assert code == 0, err
    assert "1 of 3 curves has a single vertex" in err


# -- #15, #17: dftl: attributes ---------------------------------------------------------------------------


def test_a_time_sampled_dftl_scalar_is_refused_as_time_sampled(tmp_path):
    message = refused(tmp_path, stage_text(hair="        custom float dftl:damping.timeSamples = {1: 0.5, 3: 7}"))
    assert message.startswith("/World/Hair: dftl:damping is time-sampled (2 samples at times 1..3, no default value): "
                              "not supported"), message
    assert "None" not in message


def test_a_dftl_scalar_whose_samples_equal_its_default_is_read(tmp_path):
    text = stage_text(hair="        custom float dftl:damping = 0.5\n        custom float dftl:damping.timeSamples = "
                           "{1: 0.5}")
    path = write(tmp_path, text)
    assert read_scene(path).curves[0].settings.damping == 0.5


def test_an_array_value_is_shown_plainly(tmp_path):
    assert refused(tmp_path, stage_text(hair="        custom float[] dftl:damping = [0.5, 0.5]")) == \
        "/World/Hair: dftl:damping = [0.5, 0.5]: expected a float"


# -- #18: metersPerUnit -----------------------------------------------------------------------------------


def test_a_stage_without_meters_per_unit_is_warned_about(tmp_path):
    text = stage_text(head=USDA_HEAD.replace("    metersPerUnit = 1\n", ""))
    assert "the stage does not author metersPerUnit: USD's fallback, 0.01 m per unit (centimetres), is used, so " \
           "gravity is 981 units/s^2; author metersPerUnit (1 for a scene in metres)" in warnings_of(tmp_path, text)
    assert not any("metersPerUnit" in w for w in warnings_of(tmp_path, stage_text()))
