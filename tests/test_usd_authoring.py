"""Hand-authored USD as TDs write it: attributes of an unexpected type, time-sampled widths,
references and payloads that do not resolve. Each is one line naming the file and prim (or one
warning), never a traceback."""

import pytest
from pxr import Sdf, UsdGeom
from usd_stages import USDA_HEAD, add_curves, chain, new_stage

from dftl_warp import cli
from dftl_warp.errors import UserError
from dftl_warp.usd.read import read_scene


def simulate(capsys, path, *extra):
    code = cli.main(["simulate", str(path), "-o", str(path.parent / "out.usdc"), "--end", "2", *map(str, extra)])
    out, err = capsys.readouterr()
    return code, out, err


def one_line_error(capsys, path):
    code, out, err = simulate(capsys, path)
    lines = err.strip().splitlines()
    assert code == 2 and len(lines) == 1 and "Traceback" not in err, err
    assert lines[0].startswith(f"dftl-warp: error: {path}: ")
    assert not (path.parent / "out.usdc").exists()
    return lines[0]


def hair_file(path, extra, counts="[2, 3]"):
    """A hand-written stage: /World/Hair, two linear curves of 2 and 3 points, plus ``extra``."""
    path.write_text(USDA_HEAD + f"""def Xform "World"
{{
    def BasisCurves "Hair"
    {{
        uniform token type = "linear"
        int[] curveVertexCounts = {counts}
        point3f[] points = [(0, 0, 0), (0, -0.1, 0), (0.1, 0, 0), (0.1, -0.1, 0), (0.1, -0.2, 0)]
        {extra}
    }}
}}
""")
    return path


def test_widths_of_strings_are_one_line_naming_the_prim(tmp_path, capsys):
    hair_file(tmp_path / "in.usda", 'string[] widths = ["a"] (interpolation = "constant")')
    line = one_line_error(capsys, tmp_path / "in.usda")
    assert line.endswith("/World/Hair: widths = ['a']: expected numbers (float[])")


def test_a_scalar_widths_primvar_is_one_constant_width_as_render_reads_it(tmp_path):
    """``float primvars:widths = 0.02`` (no brackets): render draws it as one width; simulate read
    it with len() and crashed. Now it is one constant width."""
    stage = new_stage(tmp_path / "in.usda")
    c = add_curves(stage, "/World/Hair", chain(5), [2, 3])
    UsdGeom.PrimvarsAPI(c).CreatePrimvar("widths", Sdf.ValueTypeNames.Float, "constant").Set(0.02)
    stage.Save()
    curves = read_scene(tmp_path / "in.usda").curves[0]
    assert curves.widths.tolist() == pytest.approx([0.02]) and curves.widths_interpolation == "constant"


def test_a_scalar_widths_of_vertex_interpolation_is_counted_like_an_array(tmp_path):
    hair_file(tmp_path / "in.usda", "float widths = 0.02")
    with pytest.raises(UserError, match=r"/World/Hair: widths: 1 values for 'vertex' interpolation, expected 5"):
        read_scene(tmp_path / "in.usda")


@pytest.mark.parametrize("counts, message", [
    ("[2.5, 2.5]", "/World/Hair: curveVertexCounts[0] = 2.5: expected a whole number (int[])"),
    ('["2", "3"]', "/World/Hair: curveVertexCounts = ['2', '3']: expected numbers (int[])"),
])
def test_curve_vertex_counts_that_are_not_whole_numbers_are_refused(tmp_path, capsys, counts, message):
    """``float[] curveVertexCounts = [2.5, 2.5]`` was truncated to [2, 2] without a word (and with
    the sum right, simulated as curves of other lengths than authored)."""
    kind = "float[]" if "." in counts else "string[]"
    path = hair_file(tmp_path / "in.usda", "", counts=counts)
    path.write_text(path.read_text().replace("int[] curveVertexCounts", f"{kind} curveVertexCounts"))
    assert one_line_error(capsys, path).endswith(message)


def test_whole_float_curve_vertex_counts_are_read(tmp_path):
    path = hair_file(tmp_path / "in.usda", "", counts="[2.0, 3.0]")
    path.write_text(path.read_text().replace("int[] curveVertexCounts", "float[] curveVertexCounts"))
    assert read_scene(path).curves[0].counts.tolist() == [2, 3]


def _sampled_widths(path, samples):
    stage = new_stage(path, start=1, end=3)
    c = add_curves(stage, "/World/Hair", chain(5, 0.1, (0, -1, 0)), [2, 3])
    c.SetWidthsInterpolation("constant")
    for t, w in samples.items():
        c.GetWidthsAttr().Set([w], t)
    stage.Save()
    return path


def test_widths_that_change_over_time_get_one_warning_naming_the_prim(tmp_path):
    """Widths keyed from 0.02 to 0.5 were read at the start frame without a word (points that change
    get a warning); now one warning names the prim and the time read."""
    scene = read_scene(_sampled_widths(tmp_path / "in.usda", {1: 0.02, 3: 0.5}))
    assert scene.curves[0].widths.tolist() == pytest.approx([0.02])
    notes = [w for w in scene.warnings if "widths" in w]
    assert notes == [f"{tmp_path / 'in.usda'}: /World/Hair: widths changes over time (2 samples): only the widths "
                     "at time 1 are read and simulated"]


def test_widths_sampled_with_one_value_are_read_without_a_warning(tmp_path):
    scene = read_scene(_sampled_widths(tmp_path / "in.usda", {1: 0.02, 2: 0.02, 3: 0.02}))
    assert not [w for w in scene.warnings if "widths" in w]


@pytest.mark.parametrize("arc, target, says", [
    ("references", "@gone.usda@", "Could not open asset @gone.usda@ for reference"),
    ("payload", "@gone.usda@", "Could not open asset @gone.usda@ for payload"),
    ("references", "@hair.usda@</Nope>", "Unresolved reference prim path"),
])
def test_a_groom_whose_reference_or_payload_did_not_load_says_so(tmp_path, capsys, arc, target, says):
    """A stage whose only hair comes through a reference or payload that does not resolve was
    refused with "no BasisCurves prims" alone (only a missing sublayer was named); now the refusal
    quotes USD's warning, for the whole stage and for a --prim at the prim that brings it in."""
    hair_file(tmp_path / "hair.usda", "")
    f = tmp_path / "shot.usda"
    f.write_text(f'#usda 1.0\n(\n    startTimeCode = 1\n    endTimeCode = 3\n)\ndef Xform "Groom" (\n    {arc} = {target}\n)\n'
                 '{\n}\ndef Xform "Other"\n{\n}\n')
    line = one_line_error(capsys, f)
    assert "the stage has no BasisCurves prims (no hair to simulate) (USD: In </Groom>: " in line and says in line
    with pytest.raises(UserError, match=r"/Groom: no BasisCurves prim at or below this path \(USD: In </Groom>: "):
        read_scene(f, prims=["/Groom"])
    with pytest.raises(UserError, match=r"/Other: no BasisCurves prim at or below this path$"):
        read_scene(f, prims=["/Other"])


@pytest.mark.parametrize("op", ['string xformOp:translate = "a"', "float3 xformOp:rotateX = (1, 2, 3)"])
def test_an_xform_op_of_the_wrong_type_is_one_line_naming_the_prim(tmp_path, capsys, op):
    """``string xformOp:translate`` above a groom raised USD's Tf.ErrorException as a traceback."""
    path = hair_file(tmp_path / "in.usda", "")
    text = path.read_text().replace('def Xform "World"\n{', 'def Xform "World"\n{\n    ' + op +
                                    '\n    uniform token[] xformOpOrder = ["' + op.split()[1] + '"]')
    path.write_text(text)
    line = one_line_error(capsys, path)
    assert "/World/Hair: local-to-world transform at time 1.0: Invalid combination of opType" in line
    assert "Returning identity" not in line


def test_usd_warnings_while_reading_are_one_line_naming_the_file(tmp_path, capsys):
    """An xformOpOrder naming an op that is not authored: USD printed its own multi-part
    "Warning: in _GetOrderedXformOps at line 686 of .../xformable.cpp -- ..." on stderr; now it is
    one dftl-warp warning naming the file (once, however many frames read the transform)."""
    path = hair_file(tmp_path / "in.usda", "")
    path.write_text(path.read_text().replace('def Xform "World"\n{', 'def Xform "World"\n{\n    uniform token[] '
                                             'xformOpOrder = ["xformOp:translate"]'))
    code, out, err = simulate(capsys, path)
    assert code == 0, err
    lines = [line for line in err.splitlines() if "xformOp:translate" in line]
    assert lines == [f"dftl-warp: warning: {path}: Unable to get attribute associated with the xformOp "
                     "'xformOp:translate', on the prim at path </World>. Skipping xformOp in the computation of the "
                     "local transformation at prim."], err
    assert "xformable.cpp" not in err


def test_points_only_time_sampled_on_a_stage_without_a_range_are_read_at_their_first_sample(tmp_path):
    """No startTimeCode and points authored only as time samples: `info` refused the prim with
    "curveVertexCounts sum to 3 but points has 0 entries" (USD has no value at the default time),
    while `simulate --start 10` read them. Now they are read at their first sample, with a warning."""
    path = tmp_path / "in.usda"
    path.write_text('#usda 1.0\ndef BasisCurves "Hair"\n{\n    uniform token type = "linear"\n'
                    '    int[] curveVertexCounts = [3]\n'
                    '    point3f[] points.timeSamples = { 10: [(0, 0, 0), (0, -1, 0), (0, -2, 0)], '
                    '20: [(0, 0, 0), (0, -1, 0), (0, -3, 0)] }\n}\n')
    scene = read_scene(path)
    assert scene.curves[0].points[:, 1].tolist() == [0, -1, -2]
    assert f"{path}: /Hair: points have only time samples and the stage no startTimeCode: read at their first " \
           "sample, time 10 (simulate reads them at --start)" in scene.warnings
    assert any("only the points at time 10 are read" in w for w in scene.warnings)
