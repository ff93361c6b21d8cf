"""Reading render input from USD: primvar interpolations, cubic curves, transforms, refits."""

import numpy as np
import pytest
from pxr import Gf, UsdGeom, Vt

from dftl_warp.errors import UserError
from dftl_warp.render import Renderer, usd_scene
from dftl_warp.render.scene import ROOT_DARKENING
from render_util import Sdf_type, add_camera, add_curves, new_stage

TWO = [np.array([[0, 0, 0], [0, 1, 0], [0, 2, 0]], float), np.array([[1, 0, 0], [1, 1, 0]], float)]


@pytest.mark.parametrize("interp,widths,radii", [
    ("constant", [0.2], [0.1] * 5),
    ("uniform", [0.2, 0.4], [0.1, 0.1, 0.1, 0.2, 0.2]),
    ("varying", [0.1, 0.2, 0.3, 0.4, 0.5], [0.05, 0.1, 0.15, 0.2, 0.25]),
    ("vertex", [0.1, 0.2, 0.3, 0.4, 0.5], [0.05, 0.1, 0.15, 0.2, 0.25]),
])
def test_width_interpolations(interp, widths, radii):
    stage = new_stage()
    add_curves(stage, "/c", TWO, widths=widths, interpolation=interp)
    scene = usd_scene.read_render_scene(stage)
    assert scene.curve_vertex_counts.tolist() == [3, 2]
    assert scene.radii == pytest.approx(radii)


def test_primvar_widths_and_indexed_display_color():
    stage = new_stage()
    c = add_curves(stage, "/c", TWO)
    pv = UsdGeom.PrimvarsAPI(c.GetPrim())
    w = pv.CreatePrimvar("widths", Sdf_type("FloatArray"), UsdGeom.Tokens.uniform)
    w.Set(Vt.FloatArray([0.5, 0.25]))
    col = pv.CreatePrimvar("displayColor", Sdf_type("Color3fArray"), UsdGeom.Tokens.vertex)
    col.Set(Vt.Vec3fArray([(1, 0, 0), (0, 1, 0)]))
    col.SetIndices(Vt.IntArray([0, 1, 1, 0, 0]))
    scene = usd_scene.read_render_scene(stage)
    assert scene.radii == pytest.approx([0.25, 0.25, 0.25, 0.125, 0.125])
    assert scene.colors.tolist() == [[1, 0, 0], [0, 1, 0], [0, 1, 0], [1, 0, 0], [1, 0, 0]]


def test_constant_and_uniform_colors_get_a_root_to_tip_ramp():
    stage = new_stage()
    add_curves(stage, "/c", TWO, colors=[(0.5, 0.4, 0.2), (0.1, 0.2, 0.3)], color_interpolation="uniform")
    scene = usd_scene.read_render_scene(stage)
    assert scene.colors[0] == pytest.approx(np.array([0.5, 0.4, 0.2]) * ROOT_DARKENING)
    assert scene.colors[2] == pytest.approx([0.5, 0.4, 0.2])
    assert scene.colors[4] == pytest.approx([0.1, 0.2, 0.3])
    # without displayColor: the default ramp, dark at the root
    stage = new_stage()
    add_curves(stage, "/c", TWO)
    cols = usd_scene.read_render_scene(stage).colors
    assert cols[0].sum() < cols[2].sum()


def test_transforms_move_points_and_scale_widths():
    stage = new_stage()
    x = UsdGeom.Xform.Define(stage, "/groom")
    x.AddTranslateOp().Set(Gf.Vec3d(10, 0, 0))
    x.AddScaleOp().Set(Gf.Vec3f(2, 2, 2))
    add_curves(stage, "/groom/c", TWO, widths=[0.1])
    scene = usd_scene.read_render_scene(stage)
    assert scene.points[1] == pytest.approx([10, 2, 0])
    assert scene.radii == pytest.approx([0.1] * 5)


def test_invisible_and_guide_prims_are_skipped():
    stage = new_stage()
    add_curves(stage, "/a", TWO)
    UsdGeom.Imageable(add_curves(stage, "/b", TWO).GetPrim()).CreateVisibilityAttr("invisible")
    UsdGeom.Imageable(add_curves(stage, "/g", TWO).GetPrim()).CreatePurposeAttr("guide")
    assert usd_scene.read_render_scene(stage).strand_count == 2


@pytest.mark.parametrize("basis,wrap,n", [("bspline", "nonperiodic", 6), ("catmullRom", "pinned", 5),
                                          ("bezier", "nonperiodic", 7), ("bspline", "periodic", 6)])
def test_cubic_curves_are_evaluated(basis, wrap, n):
    stage = new_stage()
    t = np.linspace(0, 2 * np.pi, n, endpoint=False) if wrap == "periodic" else np.linspace(0, np.pi, n)
    cv = np.stack([np.cos(t), np.sin(t), np.zeros(n)], axis=1)
    c = add_curves(stage, "/c", [cv], widths=[0.01], curve_type="cubic")
    c.CreateBasisAttr(basis)
    c.CreateWrapAttr(wrap)
    scene = usd_scene.read_render_scene(stage)
    pts = scene.points
    assert scene.curve_vertex_counts[0] == len(pts) > n
    # all evaluated points lie near the control polygon's arc (unit circle, radius within 30 %)
    assert np.all(np.abs(np.linalg.norm(pts[:, :2], axis=1) - 1) < 0.3)
    if basis == "bezier" or wrap == "pinned":  # these interpolate their end points
        assert pts[0] == pytest.approx(cv[0], abs=1e-9)
        assert pts[-1] == pytest.approx(cv[-1], abs=1e-9)


def test_animated_frames_refit_the_bvh_and_match_fresh_renders():
    stage = new_stage()
    add_camera(stage, translate=(0, 0.5, 3))
    base = [np.array([[x, 0, 0], [x, 0.5, 0.1], [x + 0.1, 1.0, 0]]) for x in np.linspace(-0.5, 0.5, 12)]
    for f in (1, 2, 3):
        add_curves(stage, "/hair", [s + [0.05 * f, 0.02 * f * s[:, 1].sum(), 0] for s in base], widths=[0.02], time=f)
    renderer = Renderer(64, 48, spp=4)
    images = [renderer.render(usd_scene.read_render_scene(stage, f), usd_scene.read_camera(stage, "/cam", f)) for f in (1, 2, 3)]
    assert renderer.bvh_builds == 1 and renderer.bvh_refits == 2
    fresh = Renderer(64, 48, spp=4).render(usd_scene.read_render_scene(stage, 3), usd_scene.read_camera(stage, "/cam", 3))
    assert np.array_equal(images[2], fresh)
    assert not np.array_equal(images[0][..., 3], images[2][..., 3])


@pytest.mark.parametrize("mutate,match", [
    (lambda c: c.GetCurveVertexCountsAttr().Set(Vt.IntArray([3, 3])), r"/c: points has 5 entries but curveVertexCounts sums to 6"),
    (lambda c: (c.CreateWidthsAttr(Vt.FloatArray([1, 2, 3])), c.SetWidthsInterpolation("vertex")), r"/c: widths: 3 values for 'vertex' interpolation, expected 5"),
    (lambda c: (c.CreateWidthsAttr(Vt.FloatArray([1, -2])), c.SetWidthsInterpolation("uniform")), r"/c: widths\[1\] is negative"),
    (lambda c: c.GetPointsAttr().Set(Vt.Vec3fArray([(0, 0, 0), (0, 1, 0), (0, float("nan"), 0), (1, 0, 0), (1, 1, 0)])), r"/c: points\[2\] is not finite"),
    (lambda c: UsdGeom.PrimvarsAPI(c.GetPrim()).CreatePrimvar("displayColor", Sdf_type("Color3fArray"), "vertex").Set(Vt.Vec3fArray([(1, 0, 0)] * 4)),
     r"/c: primvars:displayColor: 4 values for 'vertex' interpolation, expected 5"),
])
def test_bad_curves_raise_user_errors(mutate, match):
    stage = new_stage()
    mutate(add_curves(stage, "/c", TWO))
    with pytest.raises(UserError, match=r"^hair\.usda: " + match):
        usd_scene.read_render_scene(stage, None, "hair.usda")


def test_bad_mesh_and_camera_raise_user_errors():
    stage = new_stage()
    m = UsdGeom.Mesh.Define(stage, "/m")
    m.CreatePointsAttr(Vt.Vec3fArray([(0, 0, 0), (1, 0, 0), (0, 1, 0)]))
    m.CreateFaceVertexCountsAttr(Vt.IntArray([3]))
    m.CreateFaceVertexIndicesAttr(Vt.IntArray([0, 1, 7]))
    with pytest.raises(UserError, match=r"^s\.usda: /m: faceVertexIndices\[2\] = 7 is not a point index"):
        usd_scene.read_render_scene(stage, None, "s.usda")
    add_camera(stage, "/cam")
    with pytest.raises(UserError, match=r"^s\.usda: /m: no UsdGeom.Camera prim at this path \(cameras: /cam\)"):
        usd_scene.read_camera(stage, "/m", None, "s.usda")
    with pytest.raises(UserError, match=r"/nope"):
        usd_scene.read_camera(stage, "/nope", None, "s.usda")


def test_cpu_row_bands_on_threads_match_one_launch():
    stage = new_stage()
    add_camera(stage, translate=(0, 0.5, 3))
    add_curves(stage, "/hair", [np.array([[x, 0, 0], [x + 0.2, 1.0, 0.1]]) for x in np.linspace(-0.6, 0.6, 15)],
               widths=[0.02])
    scene, cam = usd_scene.read_render_scene(stage), usd_scene.read_camera(stage, "/cam")
    one = Renderer(50, 37, spp=3, threads=1).render(scene, cam)
    many = Renderer(50, 37, spp=3, threads=3).render(scene, cam)
    assert one[..., 3].sum() > 10
    assert np.array_equal(one, many)
