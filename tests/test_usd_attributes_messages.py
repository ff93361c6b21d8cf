"""The reader's messages about authored ``dftl:`` attributes: values shown as authored (a 32-bit
float with its short digits), types named in words ("an integer"), and the tool's own output
attributes (the QC, ``dftl:qc:*``) known, so reading a cache back warns about none of them."""

from __future__ import annotations

import numpy as np
import pytest
from pxr import Sdf, UsdGeom, UsdPhysics

from dftl_warp import cli
from dftl_warp.errors import UserError
from dftl_warp.output.qc import ATTRIBUTES, QC_ROOT
from dftl_warp.usd.attributes import OUTPUT_ATTRIBUTES
from dftl_warp.usd.read import read_scene

from usd_stages import add_curves, chain, new_stage, set_attr


def hair(path, end=3):
    stage = new_stage(path, start=1, end=end)
    add_curves(stage, "/World/Hair", np.concatenate([chain(4, 0.05), chain(4, 0.05, origin=(0, 0, 0.1))]), [4, 4])
    return stage


@pytest.mark.parametrize(
    "type_name, value, message",
    [
        ("Double", 2.5, "dftl:substeps = 2.5: expected an integer"),
        ("Float", 2.5, "dftl:substeps = 2.5: expected an integer"),
    ],
)
def test_an_integer_attribute_says_integer(tmp_path, type_name, value, message):
    stage = hair(tmp_path / "in.usda")
    set_attr(stage.GetPrimAtPath("/World/Hair"), "dftl:substeps", type_name, value)
    stage.Save()
    with pytest.raises(UserError) as err:
        read_scene(tmp_path / "in.usda")
    assert str(err.value) == f"{tmp_path / 'in.usda'}: /World/Hair: {message}"


def test_a_float32_value_is_shown_with_its_short_digits(tmp_path):
    stage = hair(tmp_path / "in.usda")
    ball = UsdGeom.Sphere.Define(stage, "/World/Ball")
    UsdPhysics.CollisionAPI.Apply(ball.GetPrim())
    set_attr(ball.GetPrim(), "dftl:friction", "Float", -0.3)
    set_attr(stage.GetPrimAtPath("/World/Hair"), "dftl:damping", "Float", 1.1)
    stage.Save()
    with pytest.raises(UserError) as err:
        read_scene(tmp_path / "in.usda")
    # the first bad value read: the hair's (a float32 1.1 is 1.100000023841858 as a double)
    assert str(err.value) == f"{tmp_path / 'in.usda'}: /World/Hair: dftl:damping = 1.1: must be in [0, 1]"
    stage.GetPrimAtPath("/World/Hair").RemoveProperty("dftl:damping")
    stage.Save()
    with pytest.raises(UserError) as err:
        read_scene(tmp_path / "in.usda")
    assert str(err.value) == f"{tmp_path / 'in.usda'}: /World/Ball: dftl:friction = -0.3: must be >= 0"


def test_a_double_value_keeps_its_digits(tmp_path):
    stage = hair(tmp_path / "in.usda")
    set_attr(stage.GetPrimAtPath("/World/Hair"), "dftl:damping", "Double", 1.000000001)
    stage.Save()
    with pytest.raises(UserError, match=r"dftl:damping = 1\.000000001: must be in \[0, 1\]$"):
        read_scene(tmp_path / "in.usda")


def test_the_reader_knows_every_attribute_the_qc_writes():
    assert OUTPUT_ATTRIBUTES == {*ATTRIBUTES.values(), "dftl:qc:prim"}


def test_qc_attributes_are_known_and_other_dftl_qc_names_are_not(tmp_path):
    stage = hair(tmp_path / "in.usda")
    qc = stage.DefinePrim(f"{QC_ROOT}/World_Hair", "Scope")
    set_attr(qc, "dftl:qc:prim", "String", "/World/Hair")
    for name in ATTRIBUTES.values():
        set_attr(qc, name, "Int" if name.endswith("nanCount") else "Double", 0)
    set_attr(qc, "dftl:qc:maxStrech", "Double", 0.0)  # not a name dftl-warp writes
    stage.Save()
    warnings = [w for w in read_scene(tmp_path / "in.usda").warnings if "unknown" in w]
    assert len(warnings) == 1
    # a misspelt QC name is suggested among the QC's names, not the attributes read
    assert warnings[0] == (f"{tmp_path / 'in.usda'}: {QC_ROOT}/World_Hair: unknown attribute dftl:qc:maxStrech "
                           "(did you mean dftl:qc:maxStretch?); ignored")


def test_a_cache_read_back_gets_no_unknown_attribute_warning(tmp_path, capsys):
    stage = hair(tmp_path / "in.usda")
    stage.Save()
    out = tmp_path / "o.usda"
    assert cli.main(["simulate", str(tmp_path / "in.usda"), "-o", str(out), "--quiet", "--device", "cpu"]) == 0
    assert Sdf.Layer.FindOrOpen(str(out)).GetPrimAtPath(QC_ROOT)  # the cache holds the QC
    assert not [w for w in read_scene(out).warnings if "unknown" in w]
    capsys.readouterr()
    assert cli.main(["info", str(out)]) == 0
    captured = capsys.readouterr()
    assert "unknown attributes" not in captured.out + captured.err and "dftl:qc" not in captured.out
    # the cache as the input of another run
    assert cli.main(["simulate", str(out), "-o", str(tmp_path / "o2.usda"), "--device", "cpu"]) == 0
    captured = capsys.readouterr()
    assert "unknown attributes" not in captured.out + captured.err
