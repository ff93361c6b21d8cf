"""Reading rules: stage metadata, units, gravity, curves, settings, selection, colliders."""

import numpy as np
import pytest
from pxr import Gf, Sdf, UsdGeom, UsdPhysics, UsdShade, UsdUtils, Vt
from usd_stages import add_curves, chain, new_stage, set_attr

from dftl_warp.errors import UserError
from dftl_warp.usd.read import read_scene


def simple(tmp_path, name="in.usda", **stage_kw):
    stage = new_stage(tmp_path / name, **stage_kw)
    add_curves(stage, "/World/Hair", np.concatenate([chain(3), chain(2, origin=(0, 0, 1))]), [3, 2])
    return stage


def test_stage_metadata_and_default_gravity_metres_y_up(tmp_path):
    simple(tmp_path, up="Y", meters_per_unit=1.0, start=3, end=12, fps=30.0).Save()
    scene = read_scene(tmp_path / "in.usda")
    info = scene.stage
    assert (info.up_axis, info.meters_per_unit, info.time_codes_per_second) == ("Y", 1.0, 30.0)
    assert (info.start_time_code, info.end_time_code, info.default_prim) == (3.0, 12.0, "World")
    np.testing.assert_allclose(scene.gravity, [0.0, -9.81, 0.0])
    assert scene.num_strands == 2 and scene.num_points == 5
    c = scene.curves[0]
    assert c.path == "/World/Hair" and c.type == "linear" and c.wrap == "nonperiodic"
    np.testing.assert_array_equal(c.root_indices, [0, 3])
    assert not c.animated and scene.colliders == []


def test_centimetre_z_up_gravity_in_stage_units(tmp_path):
    simple(tmp_path, up="Z", meters_per_unit=0.01).Save()
    scene = read_scene(tmp_path / "in.usda")
    np.testing.assert_allclose(scene.gravity, [0.0, 0.0, -981.0])
    np.testing.assert_allclose(scene.gravity_si, [0.0, 0.0, -9.81])


def test_unauthored_meters_per_unit_means_centimetres(tmp_path):
    simple(tmp_path, up=None, meters_per_unit=None).Save()
    scene = read_scene(tmp_path / "in.usda")
    assert scene.stage.meters_per_unit == 0.01
    assert "metersPerUnit" not in scene.stage.authored
    np.testing.assert_allclose(scene.gravity, [0.0, -981.0, 0.0])


def test_frames_per_second_stands_in_for_time_codes_per_second(tmp_path):
    stage = simple(tmp_path, fps=None)
    stage.SetFramesPerSecond(30.0)
    stage.Save()
    info = read_scene(tmp_path / "in.usda").stage
    assert info.time_codes_per_second == 30.0 and info.frames_per_second == 30.0


@pytest.mark.parametrize(
    "direction, magnitude, expected",
    [
        ((1.0, 0.0, 0.0), 5.0, (5.0, 0.0, 0.0)),
        ((0.0, 0.0, -2.0), 3.0, (0.0, 0.0, -3.0)),  # normalized
        ((0.0, 0.0, 0.0), 4.0, (0.0, 0.0, -4.0)),  # zero direction: -upAxis (Z)
        ((0.0, -1.0, 0.0), -1.0, (0.0, -981.0, 0.0)),  # negative magnitude: earth gravity, in cm
        (None, None, (0.0, 0.0, -981.0)),  # nothing authored: both fallbacks
    ],
)
def test_physics_scene_gravity(tmp_path, direction, magnitude, expected):
    stage = simple(tmp_path, up="Z", meters_per_unit=0.01)
    phys = UsdPhysics.Scene.Define(stage, "/World/Physics")
    if direction is not None:
        phys.CreateGravityDirectionAttr(Gf.Vec3f(*direction))
    if magnitude is not None:
        phys.CreateGravityMagnitudeAttr(magnitude)
    stage.Save()
    np.testing.assert_allclose(read_scene(tmp_path / "in.usda").gravity, expected, rtol=1e-6)


def test_cubic_curves_keep_control_points_type_basis_wrap(tmp_path):
    stage = new_stage(tmp_path / "in.usda")
    pts = chain(7, spacing=0.5)
    add_curves(stage, "/World/Bez", pts, [7], curve_type="cubic", basis="bezier")
    add_curves(stage, "/World/Bsp", pts[:5], [5], curve_type="cubic", basis="bspline", wrap="pinned")
    add_curves(stage, "/World/Cr", pts[:4], [4], curve_type="cubic", basis="catmullRom")
    stage.Save()
    scene = read_scene(tmp_path / "in.usda")
    got = {c.path: (c.type, c.basis, c.wrap, c.num_points) for c in scene.curves}
    assert got == {
        "/World/Bez": ("cubic", "bezier", "nonperiodic", 7),
        "/World/Bsp": ("cubic", "bspline", "pinned", 5),
        "/World/Cr": ("cubic", "catmullRom", "nonperiodic", 4),
    }
    np.testing.assert_allclose(scene.curves[0].points, pts)


def test_points_widths_color_read_at_the_start_time_code(tmp_path):
    stage = new_stage(tmp_path / "in.usda", start=5, end=9)
    c = add_curves(stage, "/World/Hair", chain(3), [3], widths=[0.1, 0.2, 0.3])
    c.GetPointsAttr().Set(Vt.Vec3fArray.FromNumpy(chain(3, origin=(0, 7, 0)).astype(np.float32)), 5.0)
    c.GetPointsAttr().Set(Vt.Vec3fArray.FromNumpy(chain(3, origin=(0, 9, 0)).astype(np.float32)), 9.0)
    c.CreateDisplayColorPrimvar(UsdGeom.Tokens.constant).Set([(0.5, 0.25, 0.125)])
    stage.Save()
    scene = read_scene(tmp_path / "in.usda")
    curves = scene.curves[0]
    assert scene.read_time == 5.0
    np.testing.assert_allclose(curves.points[:, 1], 7.0)
    np.testing.assert_allclose(curves.widths, [0.1, 0.2, 0.3], rtol=1e-6)
    assert curves.widths_interpolation == "vertex"
    np.testing.assert_allclose(curves.display_color, [[0.5, 0.25, 0.125]])
    assert curves.display_color_interpolation == "constant"
    np.testing.assert_allclose(read_scene(tmp_path / "in.usda", time=9).curves[0].points[:, 1], 9.0)


def test_dftl_settings_are_read(tmp_path):
    stage = simple(tmp_path)
    prim = stage.GetPrimAtPath("/World/Hair")
    set_attr(prim, "dftl:damping", "Float", 0.25)
    set_attr(prim, "dftl:correction", "Token", "posterior")
    set_attr(prim, "dftl:substeps", "Int", 3)
    set_attr(prim, "dftl:solver", "Token", "ftl")
    stage.Save()
    s = read_scene(tmp_path / "in.usda").curves[0].settings
    assert (s.damping, s.correction, s.substeps, s.solver, s.simulate) == (0.25, "posterior", 3, "ftl", True)


@pytest.mark.parametrize(
    "name, type_name, value, message",
    [
        ("dftl:damping", "Float", 1.5, "dftl:damping = 1.5: must be in [0, 1]"),
        ("dftl:damping", "String", "high", "dftl:damping = 'high': expected a float"),
        ("dftl:correction", "Token", "sideways", "dftl:correction = 'sideways': choose prior or posterior"),
        ("dftl:substeps", "Int", 0, "dftl:substeps = 0: must be >= 1"),
        ("dftl:substeps", "Double", 2.5, "dftl:substeps = 2.5: expected an integer"),
        ("dftl:solver", "Token", "magic", "dftl:solver = 'magic': choose one of"),
        ("dftl:simulate", "Int", 1, "dftl:simulate = 1: expected a bool"),
    ],
)
def test_bad_dftl_settings_are_refused(tmp_path, name, type_name, value, message):
    stage = simple(tmp_path)
    set_attr(stage.GetPrimAtPath("/World/Hair"), name, type_name, value)
    stage.Save()
    with pytest.raises(UserError) as err:
        read_scene(tmp_path / "in.usda")
    assert str(err.value).startswith(f"{tmp_path / 'in.usda'}: /World/Hair: {message}")


def test_dftl_simulate_false_leaves_a_prim_out(tmp_path):
    stage = simple(tmp_path)
    add_curves(stage, "/World/Other", chain(2), [2])
    set_attr(stage.GetPrimAtPath("/World/Other"), "dftl:simulate", "Bool", False)
    stage.Save()
    scene = read_scene(tmp_path / "in.usda")
    assert [c.path for c in scene.curves] == ["/World/Hair"]
    assert any("dftl:simulate = false" in w for w in scene.warnings)


def test_prim_selection(tmp_path):
    stage = new_stage(tmp_path / "in.usda")
    add_curves(stage, "/World/A/Hair", chain(2), [2])
    add_curves(stage, "/World/A/More", chain(3), [3])
    add_curves(stage, "/World/B/Hair", chain(4), [4])
    UsdGeom.Xform.Define(stage, "/World/Empty")
    stage.Save()
    f = tmp_path / "in.usda"
    assert [c.path for c in read_scene(f, prims=["/World/A"]).curves] == ["/World/A/Hair", "/World/A/More"]
    assert [c.path for c in read_scene(f, prims=["/World/B/Hair", "/World/A/More"]).curves] == [
        "/World/B/Hair", "/World/A/More"]
    with pytest.raises(UserError, match=r"/World/Nope: no such prim"):
        read_scene(f, prims=["/World/Nope"])
    with pytest.raises(UserError, match=r"/World/Empty: no BasisCurves prim at or below this path"):
        read_scene(f, prims=["/World/Empty"])
    with pytest.raises(UserError, match=r"World: not an absolute prim path"):
        read_scene(f, prims=["World"])


def test_colliders_are_read_with_shapes_and_friction(tmp_path):
    stage = simple(tmp_path)
    sphere = UsdGeom.Sphere.Define(stage, "/World/Head")
    sphere.CreateRadiusAttr(2.0)
    UsdPhysics.CollisionAPI.Apply(sphere.GetPrim())
    set_attr(sphere.GetPrim(), "dftl:friction", "Float", 0.3)
    cap = UsdGeom.Capsule.Define(stage, "/World/Neck")
    cap.CreateRadiusAttr(0.5)
    cap.CreateHeightAttr(1.5)
    cap.CreateAxisAttr("Y")
    UsdPhysics.CollisionAPI.Apply(cap.GetPrim())
    material = UsdShade.Material.Define(stage, "/World/Skin")
    UsdPhysics.MaterialAPI.Apply(material.GetPrim()).CreateDynamicFrictionAttr(0.6)
    UsdShade.MaterialBindingAPI.Apply(cap.GetPrim()).Bind(material, UsdShade.Tokens.weakerThanDescendants, "physics")
    cube = UsdGeom.Cube.Define(stage, "/World/Box")
    cube.CreateSizeAttr(4.0)
    UsdPhysics.CollisionAPI.Apply(cube.GetPrim())
    mesh = UsdGeom.Mesh.Define(stage, "/World/Quad")
    mesh.CreatePointsAttr([(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)])
    mesh.CreateFaceVertexCountsAttr([4])
    mesh.CreateFaceVertexIndicesAttr([0, 1, 2, 3])
    UsdPhysics.CollisionAPI.Apply(mesh.GetPrim())
    off = UsdGeom.Sphere.Define(stage, "/World/Disabled")
    UsdPhysics.CollisionAPI.Apply(off.GetPrim()).CreateCollisionEnabledAttr(False)
    UsdGeom.Sphere.Define(stage, "/World/NotACollider")
    stage.Save()
    scene = read_scene(tmp_path / "in.usda")
    got = {c.path: c for c in scene.colliders}
    assert sorted(got) == ["/World/Box", "/World/Head", "/World/Neck", "/World/Quad"]
    assert (got["/World/Head"].kind, got["/World/Head"].radius) == ("sphere", 2.0)
    assert got["/World/Head"].friction == pytest.approx(0.3)
    neck = got["/World/Neck"]
    assert (neck.kind, neck.radius, neck.height, neck.axis) == ("capsule", 0.5, 1.5, "Y")
    assert neck.friction == pytest.approx(0.6)
    np.testing.assert_allclose(got["/World/Box"].half_extents, [2.0, 2.0, 2.0])
    assert got["/World/Box"].friction is None
    quad = got["/World/Quad"]
    np.testing.assert_array_equal(quad.triangles, [[0, 1, 2], [0, 2, 3]])
    assert quad.mesh_points.shape == (4, 3)


def test_bad_collider_mesh_is_refused_with_its_index(tmp_path):
    stage = simple(tmp_path)
    mesh = UsdGeom.Mesh.Define(stage, "/World/Bad")
    mesh.CreatePointsAttr([(0, 0, 0), (1, 0, 0), (1, 1, 0)])
    mesh.CreateFaceVertexCountsAttr([3])
    mesh.CreateFaceVertexIndicesAttr([0, 1, 7])
    UsdPhysics.CollisionAPI.Apply(mesh.GetPrim())
    stage.Save()
    with pytest.raises(UserError, match=r"in.usda: /World/Bad: faceVertexIndices\[2\] = 7 is out of range"):
        read_scene(tmp_path / "in.usda")


def test_usdz_input(tmp_path):
    simple(tmp_path).Save()
    assert UsdUtils.CreateNewUsdzPackage(Sdf.AssetPath(str(tmp_path / "in.usda")), str(tmp_path / "in.usdz"))
    scene = read_scene(tmp_path / "in.usdz")
    assert scene.num_strands == 2 and scene.source.endswith("in.usdz")


def test_missing_sublayer_is_a_warning_not_an_error(tmp_path):
    stage = simple(tmp_path)
    stage.GetRootLayer().subLayerPaths.append("./missing.usda")
    stage.Save()
    scene = read_scene(tmp_path / "in.usda")
    assert scene.num_strands == 2
    assert any("missing.usda" in w and "\n" not in w for w in scene.warnings)


def test_animated_ancestor_makes_the_prim_animated(tmp_path):
    stage = new_stage(tmp_path / "in.usda")
    xf = UsdGeom.Xform.Define(stage, "/World/Head")
    op = xf.AddTranslateOp()
    op.Set(Gf.Vec3d(0, 0, 0), 1)
    op.Set(Gf.Vec3d(10, 0, 0), 10)
    add_curves(stage, "/World/Head/Hair", chain(2), [2])
    stage.Save()
    c = read_scene(tmp_path / "in.usda").curves[0]
    assert c.animated
    np.testing.assert_allclose(c.transform(5.5)[3, :3], [5.0, 0.0, 0.0])
