"""Renderer coverage against an independent projection through the same USD camera.

The expected coverage is computed in numpy: rays through an 8 x 8 grid in every pixel are
unprojected with the camera's own Gf.Frustum matrices (pxr, conformed to the image aspect) and
tested against the strand tubes (capsule chains) by exact ray-segment distances.
"""

import numpy as np
import pytest

from dftl_warp.render import Renderer
from dftl_warp.render import usd_scene
from render_util import (add_camera, add_curves, alpha_centroid, expected_tube_coverage, gf_view_projection,
                         new_stage, pixel_rays)

W, H = 120, 90  # image aspect 4:3 against a 3:2 aperture: the window is conformed
SUB = 8


def strand_layout():
    """Five strands in front of the camera: straight, kinked, oblique, foreshortened."""
    s1 = np.array([[-0.30, -0.20, 0.0], [-0.30, 0.25, 0.0]])
    s2 = np.array([[-0.15, -0.25, 0.05], [-0.05, 0.0, 0.05], [-0.12, 0.22, 0.0]])
    s3 = np.array([[0.0, -0.2, -0.1], [0.3, 0.2, 0.1]])
    s4 = np.array([[0.2, -0.25, -0.3], [0.22, -0.05, 0.2]])  # towards the camera
    s5 = np.array([[-0.35, 0.3, 0.0], [0.0, 0.32, -0.05], [0.35, 0.28, 0.0], [0.35, 0.1, 0.0]])
    return [s1, s2, s3, s4, s5]


def make_stage(width=0.02, projection="perspective", interpolation="constant", widths=None):
    stage = new_stage()
    strands = strand_layout()
    add_curves(stage, "/hair", strands, widths=width if widths is None else widths, interpolation=interpolation)
    aperture = (36.0, 24.0) if projection == "perspective" else (9.0, 6.0)
    add_camera(stage, translate=(0.1, 0.15, 1.3), rotate_xyz=(-6.0, 4.0, 0.0), focal=50.0, aperture=aperture,
               offset=(1.5, -0.8), clipping=(0.1, 10.0), projection=projection)
    return stage, strands


def render(stage, spp=64, policy="expandAperture", width=W, height=H):
    scene = usd_scene.read_render_scene(stage, None, "test.usda")
    cam = usd_scene.read_camera(stage, "/cam", None, "test.usda")
    return Renderer(width, height, spp=spp, conform=policy).render(scene, cam)


def expected(stage, strands, radii, policy="expandAperture", width=W, height=H):
    vp, _ = gf_view_projection(stage, "/cam", width, height, policy)
    o, d = pixel_rays(vp, width, height, SUB)
    cover = expected_tube_coverage(o, d, strands, radii)
    centre = expected_tube_coverage(*pixel_rays(vp, width, height, 1), strands, radii)
    return cover, centre, (o, d)


def pixel_margin_masks(stage, strands, radius, width=W, height=H):
    """Pixels whose every point is inside (resp. outside) the tubes: decided from the pixel
    centre's ray distance with a margin of a pixel's diagonal at that depth."""
    from render_util import ray_segment_distance

    vp, px_tan = gf_view_projection(stage, "/cam", width, height)
    o, d = pixel_rays(vp, width, height, 1)
    o, d = o[:, :, 0], d[:, :, 0]
    best = np.full(o.shape[:2], np.inf)
    best_t = np.zeros(o.shape[:2])
    for pts in strands:
        for i in range(len(pts) - 1):
            dist, t = ray_segment_distance(o, d, pts[i], pts[i + 1])
            better = dist < best
            best, best_t = np.where(better, dist, best), np.where(better, t, best_t)
    # distance from the near-plane origin + near distance ~ distance from the eye: a pixel's
    # world size at depth t is about t * px_tan (perspective)
    margin = 0.75 * (best_t + 1.0) * px_tan
    return best < radius - margin, best > radius + margin


@pytest.mark.parametrize("projection", ["perspective", "orthographic"])
def test_alpha_coverage_matches_independent_projection(projection):
    stage, strands = make_stage(width=0.04, projection=projection)
    img = render(stage)
    alpha = img[..., 3]
    cover, centre, _ = expected(stage, strands, [0.02] * len(strands))
    assert cover.sum() > 200  # the strands are in view
    # covered area (in pixels) within 2 %
    assert abs(alpha.sum() - cover.sum()) / cover.sum() < 0.02
    # pixel by pixel: only sampling noise on edges
    assert np.abs(alpha - cover).mean() < 0.01
    assert np.abs(alpha - cover).max() < 0.35
    # binary masks at half coverage agree almost everywhere
    a, e = alpha > 0.5, cover > 0.5
    iou = (a & e).sum() / (a | e).sum()
    assert iou > 0.92
    if projection == "perspective":
        inside, outside = pixel_margin_masks(stage, strands, 0.02)
        assert inside.sum() > 50
        assert (alpha[inside] == 1.0).all()
        assert (alpha[outside] == 0.0).all()


def test_widths_change_coverage_as_expected():
    stage1, strands = make_stage(width=0.01)
    stage2, _ = make_stage(width=0.02)
    stage4, _ = make_stage(width=0.04)
    a1, a2, a4 = (render(s, spp=36)[..., 3].sum() for s in (stage1, stage2, stage4))
    e1, e2, e4 = (expected(s, strands, [r] * 5)[0].sum() for s, r in ((stage1, 0.005), (stage2, 0.01), (stage4, 0.02)))
    assert a1 < a2 < a4
    for a, e in ((a1, e1), (a2, e2), (a4, e4)):
        assert abs(a - e) / e < 0.03
    # thin tubes: area grows about linearly with width (caps and overlaps aside)
    assert 1.7 < a2 / a1 < 2.1 and 1.7 < a4 / a2 < 2.1


def test_uniform_and_vertex_widths():
    strands = strand_layout()
    per_curve = np.array([0.0, 0.02, 0.01, 0.03, 0.015])
    stage, _ = make_stage(widths=per_curve, interpolation="uniform")
    alpha = render(stage, spp=36)[..., 3]
    e = expected(stage, strands, list(per_curve / 2))[0]
    assert abs(alpha.sum() - e.sum()) / e.sum() < 0.03
    # tapered strands (vertex widths: 0.03 at the root to 0.005 at the tip)
    taper = [np.linspace(0.03, 0.005, len(s)) for s in strands]
    stage, _ = make_stage(widths=np.concatenate(taper), interpolation="vertex")
    alpha = render(stage, spp=36)[..., 3]
    e = expected(stage, strands, [t / 2 for t in taper])[0]
    assert abs(alpha.sum() - e.sum()) / e.sum() < 0.03
    assert np.abs(alpha - e).mean() < 0.01


def test_empty_stage_renders_transparent():
    stage = new_stage()
    add_camera(stage)
    stage.DefinePrim("/world", "Xform")
    scene = usd_scene.read_render_scene(stage, None, "empty.usda")
    assert scene.is_empty()
    img = Renderer(64, 48, spp=4).render(scene, usd_scene.read_camera(stage, "/cam"))
    assert img.shape == (48, 64, 4)
    assert (img == 0).all()
    # and without a camera (automatic framing of nothing)
    assert (Renderer(32, 16, spp=2).render(scene) == 0).all()


@pytest.mark.parametrize("policy", ["expandAperture", "cropAperture", "adjustApertureWidth", "adjustApertureHeight"])
@pytest.mark.parametrize("size", [(120, 60), (60, 120)])
def test_camera_aspect_and_aperture_conform(policy, size):
    """A small sphere lands where the conformed Gf frustum projects its centre."""
    from pxr import Gf, UsdGeom

    width, height = size
    stage = new_stage()
    add_camera(stage, translate=(0.0, 0.0, 2.0), aperture=(36.0, 24.0), offset=(2.0, 1.0))
    centre = np.array([0.12, -0.07, 0.0])
    sphere = UsdGeom.Sphere.Define(stage, "/ball")
    sphere.CreateRadiusAttr(0.03)
    sphere.AddTranslateOp().Set(Gf.Vec3d(*centre))
    img = render(stage, spp=64, policy=policy, width=width, height=height)
    vp, _ = gf_view_projection(stage, "/cam", width, height, policy)
    clip = np.r_[centre, 1.0] @ vp
    ndc = clip[:2] / clip[3]
    expect = ((ndc[0] + 1) / 2 * width, (1 - ndc[1]) / 2 * height)
    got = alpha_centroid(img[..., 3])
    assert np.allclose(got, expect, atol=0.3), (got, expect)
    # and the disc's area matches the expected coverage of the sphere
    o, d = pixel_rays(vp, width, height, SUB)
    oc = o - centre
    b = np.einsum("...k,...k->...", oc, d)
    disc = (b * b - (np.einsum("...k,...k->...", oc, oc) - 0.03 ** 2) >= 0).mean(axis=-1)
    assert abs(img[..., 3].sum() - disc.sum()) / disc.sum() < 0.03


def test_conformed_window_numbers():
    from dftl_warp.render.camera import Camera

    cam = Camera(np.eye(4), focal_length=50.0, horizontal_aperture=36.0, vertical_aperture=24.0)
    assert cam.conformed_window(300, 200) == pytest.approx((-18, 18, -12, 12))
    assert cam.conformed_window(400, 200, "expandAperture") == pytest.approx((-24, 24, -12, 12))
    assert cam.conformed_window(400, 200, "cropAperture") == pytest.approx((-18, 18, -9, 9))
    assert cam.conformed_window(200, 200, "expandAperture") == pytest.approx((-18, 18, -18, 18))
    assert cam.conformed_window(200, 200, "cropAperture") == pytest.approx((-12, 12, -12, 12))
    assert cam.conformed_window(200, 200, "adjustApertureHeight") == pytest.approx((-18, 18, -18, 18))
    # projecting the aperture corners of an image of the aperture's aspect hits the image corners
    px, depth = cam.world_to_pixel([[-18 / 50, -12 / 50, -1.0], [18 / 50, 12 / 50, -1.0]], 300, 200)
    assert px == pytest.approx(np.array([[0.0, 200.0], [300.0, 0.0]]))


def test_sphere_cube_and_mesh_coverage():
    """Gprims and meshes are drawn where the USD camera sees them."""
    from pxr import Gf, UsdGeom, Vt

    stage = new_stage()
    add_camera(stage, translate=(0.0, 0.0, 2.0))
    quad = UsdGeom.Mesh.Define(stage, "/quad")
    quad.CreatePointsAttr(Vt.Vec3fArray([(-0.3, -0.2, 0), (0.1, -0.2, 0), (0.1, 0.2, 0), (-0.3, 0.2, 0)]))
    quad.CreateFaceVertexCountsAttr(Vt.IntArray([4]))
    quad.CreateFaceVertexIndicesAttr(Vt.IntArray([0, 1, 2, 3]))
    cube = UsdGeom.Cube.Define(stage, "/box")
    cube.CreateSizeAttr(0.1)
    cube.AddTranslateOp().Set(Gf.Vec3d(0.3, 0.2, 0.0))
    img = render(stage, spp=16)
    vp, _ = gf_view_projection(stage, "/cam", W, H)
    clip = np.array([[-0.3, -0.2, 0, 1], [0.1, 0.2, 0, 1]]) @ vp
    ndc = clip[:, :2] / clip[:, 3:]
    x = (ndc[:, 0] + 1) / 2 * W
    y = (1 - ndc[:, 1]) / 2 * H
    quad_area = abs(x[1] - x[0]) * abs(y[1] - y[0])
    alpha = img[..., 3]
    cx0, cx1 = int(np.ceil(min(x))), int(np.floor(max(x)))
    cy0, cy1 = int(np.ceil(min(y))), int(np.floor(max(y)))
    assert (alpha[cy0:cy1, cx0:cx1] == 1.0).all()
    # quad + the cube's front face (a 0.1 square at z = 0.05) + its visible sides
    clipc = np.array([[0.25, 0.15, 0.05, 1], [0.35, 0.25, 0.05, 1]]) @ vp
    ndcc = clipc[:, :2] / clipc[:, 3:]
    cube_front = abs(ndcc[1, 0] - ndcc[0, 0]) * W / 2 * abs(ndcc[1, 1] - ndcc[0, 1]) * H / 2
    assert quad_area + cube_front < alpha.sum() < quad_area + 1.3 * cube_front
