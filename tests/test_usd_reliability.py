"""USD input reliability (issue 18, the reader's parts): misspelt dftl: attributes, stage metadata,
empty meshes, instanced grooms, animated points, cubic vertex counts, widths; and a Scene that is
plain data (no open stage)."""

import gc
import pickle

import numpy as np
import pytest
from pxr import Gf, Sdf, Usd, UsdGeom, UsdPhysics, Vt
from usd_stages import add_curves, animated_xform, chain, new_stage, set_attr

from dftl_warp import cli
from dftl_warp.errors import UserError
from dftl_warp.usd.read import read_scene


def simulate(capsys, path, *extra):
    code = cli.main(["simulate", str(path), "-o", str(path.parent / "out.usdc"), "--end", "2", *map(str, extra)])
    out, err = capsys.readouterr()
    return code, out, err


def assert_one_line_error(capsys, path, *pieces):
    code, out, err = simulate(capsys, path)
    lines = err.strip().splitlines()
    assert code == 2 and len(lines) == 1 and "Traceback" not in err, err
    for piece in pieces:
        assert piece in lines[0], (piece, lines[0])
    assert not (path.parent / "out.usdc").exists()
    return lines[0]


# -- 2. misspelt dftl: attributes --------------------------------------------------------------


def test_misspelt_attributes_warn_once_per_prim_with_did_you_mean(tmp_path, capsys):
    stage = new_stage(tmp_path / "in.usda")
    hair = add_curves(stage, "/World/Hair", chain(3), [3]).GetPrim()
    set_attr(hair, "dftl:dampng", "Float", 0.5)
    set_attr(hair, "dftl:substep", "Int", 2)
    set_attr(hair, "dftl:damping", "Float", 0.5)  # a known one: no warning
    set_attr(stage.GetPrimAtPath("/World"), "dftl:hairhair", "Bool", True)
    stage.Save()
    scene = read_scene(tmp_path / "in.usda")
    notes = [w for w in scene.warnings if "unknown attribute" in w]
    assert len(notes) == 2, scene.warnings
    hair_note = next(w for w in notes if "/World/Hair" in w)
    assert hair_note.startswith(f"{tmp_path / 'in.usda'}: /World/Hair: unknown attributes ")
    assert "dftl:dampng (did you mean dftl:damping?)" in hair_note
    assert "dftl:substep (did you mean dftl:substeps?)" in hair_note
    assert "dftl:hairhair (did you mean dftl:hairHair?)" in next(w for w in notes if w != hair_note)
    assert scene.curves[0].settings.damping == 0.5
    # the command prints them (once each), and still succeeds
    code, out, err = simulate(capsys, tmp_path / "in.usda")
    assert code == 0, err
    assert err.count("did you mean dftl:damping?") == 1 and err.count("dftl:hairhair") == 1


def test_known_attributes_on_prims_that_do_not_read_them_warn(tmp_path):
    stage = new_stage(tmp_path / "in.usda")
    UsdGeom.Xform.Define(stage, "/World/Head")
    add_curves(stage, "/World/Head/Hair", chain(3), [3])
    set_attr(stage.GetPrimAtPath("/World/Head"), "dftl:damping", "Float", 0.5)
    stage.Save()
    notes = [w for w in read_scene(tmp_path / "in.usda").warnings if "/World/Head:" in w]
    assert len(notes) == 1 and "not read on this prim: dftl:damping (read on BasisCurves prims)" in notes[0]


# -- 4. stage metadata and empty meshes --------------------------------------------------------


@pytest.mark.parametrize("tcps", [0.0, -24.0])
def test_bad_time_codes_per_second_is_one_line(tmp_path, capsys, tcps):
    stage = new_stage(tmp_path / "in.usda")
    add_curves(stage, "/World/Hair", chain(3), [3])
    stage.SetTimeCodesPerSecond(tcps)
    stage.Save()
    assert_one_line_error(capsys, tmp_path / "in.usda", f"{tmp_path / 'in.usda'}: timeCodesPerSecond = {tcps:g}: "
                          "must be a positive number")


def test_mesh_collider_without_faces_is_one_line(tmp_path, capsys):
    stage = new_stage(tmp_path / "in.usda")
    add_curves(stage, "/World/Hair", chain(3), [3])
    mesh = UsdGeom.Mesh.Define(stage, "/World/Ground")
    mesh.CreatePointsAttr(Vt.Vec3fArray([(0, 0, 0), (1, 0, 0), (0, 0, 1)]))
    mesh.CreateFaceVertexCountsAttr(Vt.IntArray([]))
    mesh.CreateFaceVertexIndicesAttr(Vt.IntArray([]))
    UsdPhysics.CollisionAPI.Apply(mesh.GetPrim())
    stage.Save()
    assert_one_line_error(capsys, tmp_path / "in.usda", f"{tmp_path / 'in.usda'}: /World/Ground: the mesh has no faces")


# -- 5. instanced grooms, animated points --------------------------------------------------------


def instanced_stage(path, instanceable=True, plain=True):
    stage = new_stage(path)
    UsdGeom.Xform.Define(stage, "/Groom")
    add_curves(stage, "/Groom/Hair", chain(3), [3])
    stage.GetPrimAtPath("/Groom").SetSpecifier(Sdf.SpecifierClass)
    inst = UsdGeom.Xform.Define(stage, "/World/Inst").GetPrim()
    inst.GetInherits().AddInherit("/Groom")
    inst.SetInstanceable(instanceable)
    if plain:
        add_curves(stage, "/World/Hair", chain(3), [3])
    stage.Save()
    return path


def test_grooms_under_instanceable_prims_are_not_simulated_and_warned(tmp_path):
    scene = read_scene(instanced_stage(tmp_path / "in.usda"))
    assert [c.path for c in scene.curves] == ["/World/Hair"]
    notes = [w for w in scene.warnings if "instanceable" in w]
    assert len(notes) == 1 and "/World/Inst: BasisCurves under an instanceable prim" in notes[0]
    assert "set instanceable = false" in notes[0]
    # de-instanced, the same groom is simulated
    scene = read_scene(instanced_stage(tmp_path / "plain.usda", instanceable=False))
    assert sorted(c.path for c in scene.curves) == ["/World/Hair", "/World/Inst/Hair"]


def test_only_instanced_grooms_or_a_selected_proxy_is_an_error(tmp_path):
    f = instanced_stage(tmp_path / "in.usda", plain=False)
    with pytest.raises(UserError, match="every BasisCurves prim is under an instanceable prim"):
        read_scene(f)
    with pytest.raises(UserError, match=r"/World/Inst/Hair: inside the instanceable prim /World/Inst"):
        read_scene(f, prims=["/World/Inst/Hair"])


def test_time_sampled_points_warn_once_naming_the_prim(tmp_path):
    stage = new_stage(tmp_path / "in.usda")
    curves = add_curves(stage, "/World/Hair", chain(3), [3])
    for t in (1, 5):
        curves.GetPointsAttr().Set(Vt.Vec3fArray.FromNumpy(chain(3).astype(np.float32) + t), t)
    stage.Save()
    scene = read_scene(tmp_path / "in.usda")
    notes = [w for w in scene.warnings if "time-sampled" in w]
    assert len(notes) == 1 and "/World/Hair: points are time-sampled" in notes[0] and "time 1" in notes[0]
    np.testing.assert_allclose(scene.curves[0].points, chain(3) + 1)


# -- 4/5. cubic vertex counts and widths -------------------------------------------------------


@pytest.mark.parametrize("basis, wrap, counts, bad", [
    ("bezier", None, [4, 5], 1),
    ("bezier", None, [7, 3], 1),
    ("bezier", "pinned", [6], 0),
    ("bspline", None, [4, 3], 1),
    ("catmullRom", None, [2], 0),
    ("bspline", "pinned", [1, 2], 0),
])
def test_cubic_counts_the_basis_cannot_use_are_refused(tmp_path, basis, wrap, counts, bad):
    stage = new_stage(tmp_path / "in.usda")
    add_curves(stage, "/World/Hair", chain(sum(counts)), counts, curve_type="cubic", basis=basis, wrap=wrap)
    stage.Save()
    with pytest.raises(UserError, match=rf"/World/Hair: curveVertexCounts\[{bad}\] = {counts[bad]}: .*{basis} curve needs"):
        read_scene(tmp_path / "in.usda")


@pytest.mark.parametrize("basis, wrap, counts", [
    ("bezier", None, [4, 7, 10]), ("bspline", None, [4, 9]), ("catmullRom", None, [5]), ("bspline", "pinned", [2, 3]),
])
def test_cubic_counts_the_basis_uses_are_read(tmp_path, basis, wrap, counts):
    stage = new_stage(tmp_path / "in.usda")
    add_curves(stage, "/World/Hair", chain(sum(counts)), counts, curve_type="cubic", basis=basis, wrap=wrap)
    stage.Save()
    assert read_scene(tmp_path / "in.usda").curves[0].counts.tolist() == counts


@pytest.mark.parametrize("author, message", [
    (lambda c: (c.CreateWidthsAttr(Vt.FloatArray([1, 2, 3])), c.SetWidthsInterpolation("vertex")),
     "/World/Hair: widths: 3 values for 'vertex' interpolation, expected 5"),
    (lambda c: (c.CreateWidthsAttr(Vt.FloatArray([1, -2])), c.SetWidthsInterpolation("uniform")),
     r"/World/Hair: widths[1] is negative"),
    (lambda c: UsdGeom.PrimvarsAPI(c).CreatePrimvar("widths", Sdf.ValueTypeNames.FloatArray, "uniform").Set(
        Vt.FloatArray([1, 2, 3])), "/World/Hair: primvars:widths: 3 values for 'uniform' interpolation, expected 2"),
])
def test_widths_render_refuses_are_refused_by_simulate(tmp_path, capsys, author, message):
    from dftl_warp.render import usd_scene

    stage = new_stage(tmp_path / "in.usda")
    c = add_curves(stage, "/World/Hair", chain(5), [2, 3])
    author(c)
    stage.Save()
    line = assert_one_line_error(capsys, tmp_path / "in.usda", message)
    assert line.startswith(f"dftl-warp: error: {tmp_path / 'in.usda'}: /World/Hair: ")
    with pytest.raises(UserError, match=r"/World/Hair: (primvars:)?widths"):  # the renderer agrees
        usd_scene.read_render_scene(Usd.Stage.Open(str(tmp_path / "in.usda")), None, "in.usda")


def test_widths_render_accepts_are_read(tmp_path):
    stage = new_stage(tmp_path / "in.usda")
    c = add_curves(stage, "/World/Hair", chain(5), [2, 3])
    c.CreateWidthsAttr(Vt.FloatArray([0.1, 0.2]))
    c.SetWidthsInterpolation("uniform")
    stage.Save()
    curves = read_scene(tmp_path / "in.usda").curves[0]
    assert curves.widths.tolist() == pytest.approx([0.1, 0.2]) and curves.widths_interpolation == "uniform"


# -- 3. the Scene is plain data ------------------------------------------------------------------


def animated_scene(path):
    stage = new_stage(path, start=1, end=12)
    animated_xform(stage, "/World/Head", translate={1: (0, 0, 0), 10: (5, 0, 0)}, rotate_y={1: 0.0, 10: 90.0})
    add_curves(stage, "/World/Head/Hair", chain(4, 0.1), [4])
    mesh = UsdGeom.Mesh.Define(stage, "/World/Head/Ground")
    mesh.CreateFaceVertexCountsAttr(Vt.IntArray([3]))
    mesh.CreateFaceVertexIndicesAttr(Vt.IntArray([0, 1, 2]))
    for t in (1, 10):
        mesh.GetPointsAttr().Set(Vt.Vec3fArray([(0, -1, 0), (1, -1, 0), (0, -1, float(t))]), t)
    UsdPhysics.CollisionAPI.Apply(mesh.GetPrim())
    stage.Save()
    return path


def test_the_scene_pickles_and_holds_no_usd_object(tmp_path):
    f = animated_scene(tmp_path / "in.usda")
    scene = read_scene(f)
    copy = pickle.loads(pickle.dumps(scene))
    for t in (1, 4, 10, 12):
        np.testing.assert_array_equal(copy.curves[0].transform(t), scene.curves[0].transform(t))
        np.testing.assert_array_equal(copy.colliders[0].points_sampler(t), scene.colliders[0].points_sampler(t))

    def walk(value, seen):
        if id(value) in seen:
            return
        seen.add(id(value))
        assert not type(value).__module__.startswith("pxr"), type(value)
        if isinstance(value, dict):
            for v in value.values():
                walk(v, seen)
        elif isinstance(value, (list, tuple)):
            for v in value:
                walk(v, seen)
        elif hasattr(value, "__dict__"):
            for v in vars(value).values():
                walk(v, seen)

    walk(scene, set())
    del scene, copy
    gc.collect()
    assert Sdf.Layer.Find(str(f)) is None  # the stage closed with the reader


def test_sampled_transforms_equal_usd_at_every_frame(tmp_path):
    f = animated_scene(tmp_path / "in.usda")
    for frames in (None, (3, 8), (1, 40)):
        scene = read_scene(f, frames=frames)
        stage = Usd.Stage.Open(str(f))
        for prim, sampler in (("/World/Head/Hair", scene.curves[0].transform),
                              ("/World/Head/Ground", scene.colliders[0].transform)):
            lo, hi = frames or (1, 12)
            for t in range(lo - 1, hi + 2):
                expected = np.array(UsdGeom.Imageable(stage.GetPrimAtPath(prim)).ComputeLocalToWorldTransform(t))
                np.testing.assert_allclose(sampler(t), expected, rtol=0, atol=1e-12, err_msg=f"{prim} {t}")
        points = UsdGeom.Mesh(stage.GetPrimAtPath("/World/Head/Ground")).GetPointsAttr()
        for t in (0, 1, 2.5, 7, 10, 30):
            np.testing.assert_allclose(scene.colliders[0].points_sampler(t), np.array(points.Get(t)), atol=1e-6)


def test_a_transform_that_goes_bad_mid_run_is_refused_up_front(tmp_path):
    stage = new_stage(tmp_path / "in.usda", start=1, end=10)
    animated_xform(stage, "/World/Head", translate={1: (0, 0, 0)})
    op = UsdGeom.Xform(stage.GetPrimAtPath("/World/Head")).AddScaleOp()
    op.Set(Gf.Vec3f(1, 1, 1), 1)
    op.Set(Gf.Vec3f(0, 0, 0), 6)
    add_curves(stage, "/World/Head/Hair", chain(3), [3])
    stage.Save()
    with pytest.raises(UserError, match=r"/World/Head/Hair: local-to-world transform at time 6.* singular"):
        read_scene(tmp_path / "in.usda")
