"""Valid-but-unusual USD as a pipeline TD authors it: scaled grooms, other curve schemas, animated
collider sizes, referenced layers in other units, cubic roots, inactive selections."""

import numpy as np
import pytest
from pxr import Gf, UsdGeom
from usd_stages import add_curves, chain, new_stage

from dftl_warp.commands.info import describe
from dftl_warp.errors import UserError
from dftl_warp.features.scene import group_features
from dftl_warp.usd.read import read_scene


def _scaled_groom(path, scale, widths):
    """A 5-point strand 4 cm long in the world, authored under a uniform ``scale``."""
    stage = new_stage(path, meters_per_unit=1.0, start=1, end=3)
    UsdGeom.Xform(stage.GetPrimAtPath("/World")).AddScaleOp().Set(Gf.Vec3d(scale, scale, scale))
    add_curves(stage, "/World/Hair", chain(5, spacing=0.01 / scale), [5], widths=widths, bending=True)
    stage.Save()
    return read_scene(path)


def test_widths_are_scaled_by_the_transform_like_the_points(tmp_path):
    # 80 um hair authored in centimetres under a 0.01 scale, and the same hair authored in metres
    scaled = _scaled_groom(tmp_path / "scaled.usda", 0.01, 0.008)
    plain = _scaled_groom(tmp_path / "plain.usda", 1.0, 0.00008)
    for scene in (scaled, plain):
        _, widths = group_features(scene, scene.curves, 1)
        np.testing.assert_allclose(widths, 0.00008, rtol=1e-6)
        np.testing.assert_allclose(describe(scene)["curves"][0]["material"]["radius"], 0.00004, rtol=1e-6)


def test_widths_under_a_non_uniform_scale_get_one_warning(tmp_path):
    stage = new_stage(tmp_path / "in.usda", meters_per_unit=1.0, start=1, end=3)
    UsdGeom.Xform(stage.GetPrimAtPath("/World")).AddScaleOp().Set(Gf.Vec3d(1.0, 2.0, 4.0))
    add_curves(stage, "/World/Hair", chain(5, spacing=0.01), [5], widths=0.0001, bending=True)
    add_curves(stage, "/World/Bald", chain(5, spacing=0.01, origin=(0, 1, 0)), [5])
    stage.Save()
    scene = read_scene(tmp_path / "in.usda")
    notes = [w for w in scene.warnings if "non-uniform scale" in w]
    assert len(notes) == 1 and "in.usda: /World/Hair: " in notes[0] and "mean scale 2" in notes[0], notes
    np.testing.assert_allclose(group_features(scene, scene.curves[:1], 1)[1], 0.0002, rtol=1e-6)


def _other_curves(stage):
    nurbs = UsdGeom.NurbsCurves.Define(stage, "/World/Nurbs")
    nurbs.CreateCurveVertexCountsAttr([4])
    nurbs.CreatePointsAttr([(0, 0, 0), (1, 0, 0), (2, 0, 0), (3, 0, 0)])
    herm = UsdGeom.HermiteCurves.Define(stage, "/World/Herm")
    herm.CreateCurveVertexCountsAttr([2])
    herm.CreatePointsAttr([(0, 0, 0), (1, 0, 0)])


def test_nurbs_and_hermite_curves_are_skipped_with_one_warning(tmp_path):
    stage = new_stage(tmp_path / "in.usda")
    add_curves(stage, "/World/Hair", chain(3), [3])
    _other_curves(stage)
    stage.Save()
    scene = read_scene(tmp_path / "in.usda")
    assert [c.path for c in scene.curves] == ["/World/Hair"]
    notes = [w for w in scene.warnings if "NurbsCurves" in w]
    assert notes == [f"{tmp_path / 'in.usda'}: 1 NurbsCurves prim (/World/Nurbs); 1 HermiteCurves prim (/World/Herm): "
                     "not simulated (only BasisCurves are); skipped"]


def test_a_stage_of_only_nurbs_curves_says_so(tmp_path):
    stage = new_stage(tmp_path / "in.usda")
    _other_curves(stage)
    stage.Save()
    with pytest.raises(UserError, match=r"no BasisCurves prims \(no hair to simulate\) \(1 NurbsCurves prim "
                                        r"\(/World/Nurbs\); 1 HermiteCurves prim \(/World/Herm\): only BasisCurves"):
        read_scene(tmp_path / "in.usda")


def _collider_stage(path):
    from pxr import UsdPhysics

    stage = new_stage(path, start=1, end=5)
    add_curves(stage, "/World/Hair", chain(3, spacing=0.1, origin=(0, 1, 0)), [3])
    rig = UsdGeom.Xform.Define(stage, "/World/Rig")
    op = rig.AddScaleOp()
    op.Set(Gf.Vec3d(1, 1, 1), 1.0)
    op.Set(Gf.Vec3d(2, 2, 2), 5.0)
    ball = UsdGeom.Sphere.Define(stage, "/World/Rig/Ball")        # grows with its parent's scale
    ball.CreateRadiusAttr(0.2)
    box = UsdGeom.Cube.Define(stage, "/World/Box")                 # its size is time-sampled
    box.CreateSizeAttr().Set(0.5, 1.0)
    box.GetSizeAttr().Set(1.0, 5.0)
    box.AddTranslateOp().Set(Gf.Vec3d(3, 0, 0))
    still = UsdGeom.Sphere.Define(stage, "/World/Still")           # moves, keeps its size: no warning
    still.CreateRadiusAttr(0.2)
    move = still.AddTranslateOp()
    move.Set(Gf.Vec3d(0, -1, 0), 1.0)
    move.Set(Gf.Vec3d(0, -2, 0), 5.0)
    for prim in (ball, box, still):
        UsdPhysics.CollisionAPI.Apply(prim.GetPrim())
    stage.Save()


def test_animated_collider_sizes_are_warned_about_once_each(tmp_path):
    _collider_stage(tmp_path / "in.usda")
    scene = read_scene(tmp_path / "in.usda")
    assert [c.path for c in scene.colliders] == ["/World/Rig/Ball", "/World/Box", "/World/Still"]
    notes = [w for w in scene.warnings if "/World/Rig/Ball" in w or "/World/Box" in w or "/World/Still" in w]
    assert len(notes) == 2, notes
    assert "/World/Rig/Ball: its scale changes over time (up to 2x its scale at time 1)" in notes[0]
    assert "/World/Box: size is time-sampled" in notes[1] and "keeps its size at time 1;" in notes[1]


def test_a_groom_under_an_animated_scale_gets_one_warning(tmp_path):
    _collider_stage(tmp_path / "in.usda")
    from pxr import Usd

    stage = Usd.Stage.Open(str(tmp_path / "in.usda"))
    add_curves(stage, "/World/Rig/Fur", chain(3, spacing=0.1, origin=(0, 1, 0)), [3])
    stage.Save()
    notes = [w for w in read_scene(tmp_path / "in.usda").warnings if "/World/Rig/Fur" in w]
    assert len(notes) == 1 and "its transform's scale changes over time (up to 2x its scale at time 1)" in notes[0]


def test_a_groom_referenced_from_a_layer_in_other_units_gets_one_warning(tmp_path):
    groom = new_stage(tmp_path / "groom.usda", up="Z", meters_per_unit=0.01, start=None, end=None)
    add_curves(groom, "/World/Hair", chain(3), [3])
    groom.Save()
    shot = new_stage(tmp_path / "shot.usda", up="Y", meters_per_unit=1.0)
    shot.DefinePrim("/World/Char").GetReferences().AddReference("./groom.usda")
    shot.DefinePrim("/World/Char2").GetReferences().AddReference("./groom.usda")
    shot.Save()
    scene = read_scene(tmp_path / "shot.usda")
    assert len(scene.curves) == 2
    notes = [w for w in scene.warnings if "groom.usda" in w]
    assert len(notes) == 1, notes
    assert "metersPerUnit 0.01 and upAxis Z, but the stage's are 1 and Y" in notes[0]
    assert not [w for w in read_scene(tmp_path / "groom.usda").warnings if "metersPerUnit" in w]


def test_nonperiodic_bspline_and_catmull_rom_roots_are_warned_about(tmp_path):
    stage = new_stage(tmp_path / "in.usda")
    pts = chain(7, spacing=0.01)
    add_curves(stage, "/World/Cr", pts, [7], curve_type="cubic", basis="catmullRom")
    add_curves(stage, "/World/Bsp", pts, [7], curve_type="cubic", basis="bspline", wrap="nonperiodic")
    add_curves(stage, "/World/Pinned", pts, [7], curve_type="cubic", basis="catmullRom", wrap="pinned")
    add_curves(stage, "/World/Bez", pts, [7], curve_type="cubic", basis="bezier")
    stage.Save()
    notes = [w for w in read_scene(tmp_path / "in.usda").warnings if "first control point" in w]
    assert [n.split(": ")[1] for n in notes] == ["/World/Cr", "/World/Bsp"], notes
    assert 'nonperiodic cubic catmullRom curves do not pass through their first control point' in notes[0]
    assert 'wrap = "pinned"' in notes[0]


def test_selecting_an_inactive_prim_says_it_is_inactive(tmp_path):
    stage = new_stage(tmp_path / "in.usda")
    add_curves(stage, "/World/Hair", chain(3), [3])
    add_curves(stage, "/World/Off/Hair", chain(3), [3])
    add_curves(stage, "/World/Bald", chain(3), [3]).GetPrim().SetActive(False)
    stage.GetPrimAtPath("/World/Off").SetActive(False)
    stage.Save()
    with pytest.raises(UserError, match=r"in.usda: /World/Bald: the prim is inactive \(active = false\)"):
        read_scene(tmp_path / "in.usda", prims=["/World/Bald"])
    with pytest.raises(UserError, match=r"in.usda: /World/Off/Hair: under the inactive prim /World/Off "
                                        r"\(active = false\)"):
        read_scene(tmp_path / "in.usda", prims=["/World/Off/Hair"])
    with pytest.raises(UserError, match=r"in.usda: /World/Nope: no such prim"):
        read_scene(tmp_path / "in.usda", prims=["/World/Nope"])


def _instancer_stage(path, *, loose_hair=True):
    stage = new_stage(path)
    if loose_hair:
        add_curves(stage, "/World/Hair", chain(3), [3])
    fur = UsdGeom.PointInstancer.Define(stage, "/World/Fur")
    add_curves(stage, "/World/Fur/Protos/Clump", chain(3), [3])
    fur.CreatePrototypesRel().SetTargets(["/World/Fur/Protos/Clump"])
    fur.CreateProtoIndicesAttr([0, 0])
    fur.CreatePositionsAttr([(1, 0, 0), (2, 0, 0)])
    stage.Save()


def test_curves_in_point_instancer_prototypes_are_skipped_with_one_warning(tmp_path):
    _instancer_stage(tmp_path / "in.usda")
    scene = read_scene(tmp_path / "in.usda")
    assert [c.path for c in scene.curves] == ["/World/Hair"]
    notes = [w for w in scene.warnings if "PointInstancer" in w]
    assert len(notes) == 1 and notes[0].startswith(f"{tmp_path / 'in.usda'}: /World/Fur: BasisCurves in the "
                                                   f"prototypes of a PointInstancer (such as /World/Fur/Protos/Clump)")
    _instancer_stage(tmp_path / "only.usda", loose_hair=False)
    with pytest.raises(UserError, match=r"only.usda: every BasisCurves prim is in the prototypes of a PointInstancer "
                                        r"\(/World/Fur\)"):
        read_scene(tmp_path / "only.usda")


@pytest.mark.parametrize("axis", ["z", "X"])
def test_an_up_axis_other_than_y_or_z_is_refused(tmp_path, axis):
    stage = new_stage(tmp_path / "in.usda", up="Y")
    add_curves(stage, "/World/Hair", chain(3), [3])
    stage.GetRootLayer().pseudoRoot.SetInfo("upAxis", axis)
    stage.Save()
    with pytest.raises(UserError, match=rf"in.usda: upAxis = '{axis}': must be \"Y\" or \"Z\""):
        read_scene(tmp_path / "in.usda")


def test_points_of_the_wrong_type_name_the_type(tmp_path):
    """``float[] points`` authored in a .usda (a flat list, not 3-vectors) is one line naming the prim
    and the type, not a count of entries that cannot match."""
    path = tmp_path / "flat.usda"
    path.write_text('#usda 1.0\n(\n    defaultPrim = "World"\n)\n\ndef Xform "World"\n{\n'
                    '    def BasisCurves "Hair"\n    {\n        int[] curveVertexCounts = [2]\n'
                    '        float[] points = [0, 0, 0, 0, -0.01, 0]\n    }\n}\n')
    with pytest.raises(UserError, match=r"/World/Hair: points is float\[\]: expected point3f\[\]"):
        read_scene(path)


@pytest.mark.parametrize("basis, wrap, n, widths, want", [
    # bezier: span ends at control points 0, 3, 6; the points between blend the two ends by index
    ("bezier", "nonperiodic", 7, [3.0, 6.0, 0.0], [3.0, 4.0, 5.0, 6.0, 4.0, 2.0, 0.0]),
    # catmullRom: span ends at control points 1 .. n - 2; the end points take the nearest end's value
    ("catmullRom", "nonperiodic", 6, [1.0, 2.0, 3.0, 4.0], [1.0, 1.0, 2.0, 3.0, 4.0, 4.0]),
    ("bspline", "pinned", 4, [1.0, 2.0, 3.0, 4.0], [1.0, 2.0, 3.0, 4.0]),   # a span end at every point
])
def test_varying_widths_of_cubic_curves_map_to_their_control_points(tmp_path, basis, wrap, n, widths, want):
    """varying widths (one per span end) of cubic curves are the hair's thickness per control point
    (they were averaged over the prim: a tapered strand simulated as one of uniform thickness)."""
    stage = new_stage(tmp_path / "in.usda", start=1, end=2)
    curves = add_curves(stage, "/World/Hair", chain(n, 0.01, direction=(0, -1, 0)), [n], curve_type="cubic",
                        basis=basis, wrap=wrap)
    curves.CreateWidthsAttr([w * 1e-5 for w in widths])
    curves.SetWidthsInterpolation("varying")
    stage.Save()
    scene = read_scene(tmp_path / "in.usda")
    _, got = group_features(scene, scene.curves, 1)
    np.testing.assert_allclose(got, np.array(want) * 1e-5, rtol=1e-6)
