"""``dftl-warp render`` on the bad inputs of the CLI audit (its items 4, 5, 10 and 11, render side).

- A schema attribute of the wrong type (Sphere ``string radius``, Camera ``string focalLength``,
  Capsule ``string radius``, Cube ``string size``) and a Capsule ``axis`` that is not X, Y or Z
  crashed with a traceback: now one line naming file, prim, attribute and value, exit 2, no image.
- A Mesh's ``holeIndices`` were ignored (hole faces drawn, indices out of range accepted) and faces
  of fewer than 3 vertices dropped without a word: holes are now left out, and bad hole indices and
  small faces are refused in the very line ``info`` (the simulation's reader) gives.
- NurbsCurves, Cylinder and Cone prims were skipped, and curves without widths drawn at a default
  width, without a word: now one warning each.
"""

import pytest

from dftl_warp import cli
from dftl_warp.render import image

HEADER = """#usda 1.0
(
    metersPerUnit = 1
    upAxis = "Y"
)
"""

HAIR = """
def BasisCurves "Hair"
{
    int[] curveVertexCounts = [3]
    point3f[] points = [(0, 0, 0), (0, -0.1, 0), (0, -0.2, 0)]
    uniform token type = "linear"
    float[] widths = [0.01] (interpolation = "constant")
}
"""


def write(tmp_path, body, hair=True, name="in.usda"):
    path = tmp_path / name
    path.write_text(HEADER + 'def Xform "World"\n{\n' + (HAIR if hair else "") + body + "\n}\n")
    return path


def render(src, out, *args):
    return cli.main(["render", str(src), "-o", str(out), "--device", "cpu", "--resolution", "32x24", "--spp", "1",
                     "-q", *map(str, args)])


def refused(capsys, src, tmp_path, *args):
    """The one error line of a render of ``src`` that must fail (exit 2, no traceback, no image)."""
    out = tmp_path / "out.png"
    assert render(src, out, *args) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err and "pxrInternal" not in err, err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("dftl-warp: error: "), err
    assert not out.exists()
    return lines[0].removeprefix("dftl-warp: error: ")


def warnings_of(capsys, src, tmp_path):
    """The warning lines of a render of ``src`` that must succeed (exit 0, an image written)."""
    out = tmp_path / "out.png"
    assert render(src, out) == 0
    err = capsys.readouterr().err
    assert "Traceback" not in err, err
    assert out.exists()
    lines = err.strip().splitlines()
    assert all(x.startswith("dftl-warp: warning: ") for x in lines), err
    return [x.removeprefix("dftl-warp: warning: ") for x in lines]


# -- item 4: schema attributes of the wrong type -----------------------------------------------------


@pytest.mark.parametrize("prim, message", [
    ('def Sphere "Head"\n{\n    string radius = "big"\n}', "/World/Head: radius = 'big': expected a number"),
    ('def Capsule "C"\n{\n    string radius = "x"\n}', "/World/C: radius = 'x': expected a number"),
    ('def Capsule "C"\n{\n    string height = "tall"\n}', "/World/C: height = 'tall': expected a number"),
    ('def Cube "C"\n{\n    string size = "x"\n}', "/World/C: size = 'x': expected a number"),
    ('def Sphere "S"\n{\n    double[] radius = [1, 2]\n}', "/World/S: radius = [1, 2]: expected a number"),
    ('def Sphere "S"\n{\n    bool radius = true\n}', "/World/S: radius = true: expected a number"),
])
def test_a_gprim_size_of_the_wrong_type_is_one_line(tmp_path, capsys, prim, message):
    """They crashed with "could not convert string to float" (a bool was drawn as radius 1)."""
    src = write(tmp_path, prim)
    assert refused(capsys, src, tmp_path) == f"{src}: {message}"


CAMERA = """
def Camera "Cam"
{{
    {attribute}
    double3 xformOp:translate = (0, -0.1, 3)
    uniform token[] xformOpOrder = ["xformOp:translate"]
}}
"""


@pytest.mark.parametrize("attribute, message", [
    ('string focalLength = "50mm"', "focalLength = '50mm': expected a number"),
    ('string horizontalAperture = "wide"', "horizontalAperture = 'wide': expected a number"),
    ('string clippingRange = "near"', "clippingRange = 'near': expected two numbers (near, far)"),
    ('uniform token projection = "fisheye"', "projection = 'fisheye': expected \"perspective\" or \"orthographic\""),
])
def test_a_camera_attribute_of_the_wrong_type_is_one_line(tmp_path, capsys, attribute, message):
    """focalLength = "50mm" crashed; an unknown projection was drawn as a perspective one without a word."""
    src = write(tmp_path, CAMERA.format(attribute=attribute))
    assert refused(capsys, src, tmp_path, "--camera", "/World/Cam") == f"{src}: /World/Cam: {message}"
    # the camera picked by default is read the same way
    assert refused(capsys, src, tmp_path) == f"{src}: /World/Cam: {message}"


def test_a_well_formed_camera_and_gprims_still_render(tmp_path, capsys):
    src = write(tmp_path, CAMERA.format(attribute="float focalLength = 35") + """
def Sphere "S"
{
    double radius = 0.02
    double3 xformOp:translate = (0.2, 0, 0)
    uniform token[] xformOpOrder = ["xformOp:translate"]
}
def Capsule "C"
{
    uniform token axis = "X"
    float radius = 0.01
    int height = 0
    double3 xformOp:translate = (-0.2, 0, 0)
    uniform token[] xformOpOrder = ["xformOp:translate"]
}
def Cube "B"
{
    float size = 0.01
    double3 xformOp:translate = (0, 0.2, 0)
    uniform token[] xformOpOrder = ["xformOp:translate"]
}""")
    assert warnings_of(capsys, src, tmp_path) == []


# -- item 5: a Capsule's axis ------------------------------------------------------------------------


@pytest.mark.parametrize("axis", ['"W"', '"x"', '"XY"', '""'])
def test_a_capsule_axis_that_is_not_x_y_or_z_is_one_line(tmp_path, capsys, axis):
    """"W" crashed ("substring not found"); "XY" and "" were drawn along X."""
    src = write(tmp_path, f'def Capsule "C"\n{{\n    uniform token axis = {axis}\n}}')
    assert refused(capsys, src, tmp_path) == (f"{src}: /World/C: axis = '{axis[1:-1]}': must be \"X\", \"Y\" or \"Z\" "
                                              "(UsdGeomCapsule's axis tokens)")


# -- item 10: Mesh holeIndices and small faces --------------------------------------------------------

#: a 2 x 1 quad at z = 0 split into its left (x < 0) and right (x > 0) faces
MESH = """
def Mesh "M" (
    prepend apiSchemas = ["PhysicsCollisionAPI"]
)
{{
    int[] faceVertexCounts = {counts}
    int[] faceVertexIndices = {indices}
    point3f[] points = [(-1, -0.5, 0), (0, -0.5, 0), (0, 0.5, 0), (-1, 0.5, 0), (1, -0.5, 0), (1, 0.5, 0)]
    {holes}
}}
"""
QUADS = dict(counts="[4, 4]", indices="[0, 1, 2, 3, 1, 4, 5, 2]")


@pytest.mark.parametrize("mesh, message", [
    (dict(QUADS, holes="int[] holeIndices = [7]"), "holeIndices[0] = 7 is out of range (0..1)"),
    (dict(QUADS, holes="int[] holeIndices = [1, -1]"), "holeIndices[1] = -1 is out of range (0..1)"),
    (dict(QUADS, holes="int[] holeIndices = [0, 1]"), "holeIndices remove every face of the mesh"),
    (dict(counts="[0, 4, 4]", indices=QUADS["indices"], holes=""),
     "faceVertexCounts[0] = 0: a face needs at least 3 vertices"),
    (dict(counts="[4, 2, 2]", indices=QUADS["indices"], holes=""),
     "faceVertexCounts[1] = 2: a face needs at least 3 vertices"),
    (dict(counts="[4, -1, 5]", indices=QUADS["indices"], holes=""),
     "faceVertexCounts[1] = -1: a face needs at least 3 vertices"),
])
def test_bad_holes_and_small_faces_are_refused_as_the_simulation_refuses_them(tmp_path, capsys, mesh, message):
    """They were accepted (the hole index out of range) or dropped (the small faces) without a word."""
    src = write(tmp_path, MESH.format(**mesh))
    line = refused(capsys, src, tmp_path)
    assert line == f"{src}: /World/M: {message}"
    # the simulation's reader (info reads the collider) says the same
    assert cli.main(["info", str(src)]) == 2
    assert capsys.readouterr().err.strip().splitlines() == [f"dftl-warp: error: {line}"]


@pytest.mark.parametrize("holes, drawn", [("", (True, True)), ("int[] holeIndices = [1]", (True, False)),
                                          ("int[] holeIndices = [0]", (False, True))])
def test_hole_faces_are_not_drawn(tmp_path, capsys, holes, drawn):
    """A camera 5 units in front of the quad sees its left face left of the image's centre and its right
    face right of it; a hole face leaves the background (alpha 0) where it was drawn filled."""
    src = write(tmp_path, MESH.format(**QUADS, holes=holes) + """
def Camera "Cam"
{
    float focalLength = 50
    float horizontalAperture = 32
    float verticalAperture = 24
    double3 xformOp:translate = (0, 0, 5)
    uniform token[] xformOpOrder = ["xformOp:translate"]
}""", hair=False)
    assert warnings_of(capsys, src, tmp_path) == []
    alpha = image.read_png(tmp_path / "out.png")[..., 3]
    assert alpha.shape == (24, 32)
    # the view is 3.2 x 2.4 units wide at the quad: a pixel is 0.1 units; x = -0.5 and x = +0.5 at columns 11 and 20
    row = alpha[12]
    assert (row[11] > 0, row[20] > 0) == drawn
    assert row[0] == 0 and row[-1] == 0   # the background beside the quad


# -- item 11: prims left out, and the default width, are said -----------------------------------------


def test_nurbs_curves_cylinders_and_cones_are_said_not_drawn(tmp_path, capsys):
    src = write(tmp_path, """
def NurbsCurves "N"
{
    int[] curveVertexCounts = [4]
    point3f[] points = [(0, 0, 0), (0, 1, 0), (1, 1, 0), (1, 0, 0)]
    int[] order = [4]
}
def Cylinder "Cy1"
{
}
def Cylinder "Cy2"
{
}
def Cone "Co"
{
}
def Cone "Hidden"
{
    token visibility = "invisible"
}
def Sphere "S"
{
    double radius = 0.02
}""")
    assert warnings_of(capsys, src, tmp_path) == [
        f"{src}: 1 NurbsCurves prim (/World/N); 2 Cylinder prims (/World/Cy1, /World/Cy2); 1 Cone prim (/World/Co): "
        "not drawn (only BasisCurves, Sphere, Capsule, Cube and Mesh prims are); skipped"]


def test_many_skipped_prims_are_one_line_naming_the_first_three(tmp_path, capsys):
    src = write(tmp_path, "".join(f'def Cylinder "C{k}"\n{{\n}}\n' for k in range(5)))
    assert warnings_of(capsys, src, tmp_path) == [
        f"{src}: 5 Cylinder prims (/World/C0, /World/C1, /World/C2 ...): not drawn (only BasisCurves, Sphere, "
        "Capsule, Cube and Mesh prims are); skipped"]


def test_curves_without_widths_are_said_to_be_drawn_at_a_default_width(tmp_path, capsys):
    bare = HAIR.replace('float[] widths = [0.01] (interpolation = "constant")', "")
    src = write(tmp_path, bare.replace('"Hair"', '"Bare"') + bare.replace('"Hair"', '"Bare2"'))
    assert warnings_of(capsys, src, tmp_path) == [
        f"{src}: 2 BasisCurves prims (/World/Bare, /World/Bare2) without widths or primvars:widths: drawn at a "
        "default width, 1/1000 of each prim's bounding-box diagonal"]
    src = write(tmp_path, bare.replace('"Hair"', '"Bare"'), hair=False, name="one.usda")
    assert warnings_of(capsys, src, tmp_path) == [
        f"{src}: 1 BasisCurves prim (/World/Bare) without widths or primvars:widths: drawn at a default width, "
        "1/1000 of its bounding-box diagonal"]
    # widths as a primvar are widths: no warning (and the Hair prim of every other test has widths)
    primvar = 'float[] primvars:widths = [0.01] (interpolation = "constant")'
    pv = bare.replace('uniform token type = "linear"', 'uniform token type = "linear"\n    ' + primvar)
    src = write(tmp_path, pv, hair=False, name="primvar.usda")
    assert warnings_of(capsys, src, tmp_path) == []


def test_a_mesh_without_faces_is_said_not_drawn(tmp_path, capsys):
    src = write(tmp_path, 'def Mesh "Empty"\n{\n}\n')
    assert warnings_of(capsys, src, tmp_path) == [
        f"{src}: 1 Mesh prim (/World/Empty) without faces (no points, faceVertexCounts or faceVertexIndices): "
        "not drawn"]



def test_a_camera_its_own_checks_refuse_is_named_with_the_file(tmp_path, capsys):
    """The camera's checks (render/camera.py) run as it is built; from a stage their line names the file."""
    src = write(tmp_path, CAMERA.format(attribute="float focalLength = 0"))
    line = refused(capsys, src, tmp_path, "--camera", "/World/Cam")
    assert line.startswith(f"{src}: ") and "focal_length = 0: must be > 0" in line


def test_an_up_axis_other_than_y_or_z_is_one_line_naming_the_file(tmp_path, capsys):
    src = tmp_path / "in.usda"
    src.write_text(write(tmp_path, "").read_text().replace('upAxis = "Y"', 'upAxis = "W"'))
    assert refused(capsys, src, tmp_path) == f"{src}: upAxis = 'W': must be \"Y\" or \"Z\""
