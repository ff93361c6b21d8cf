"""The renderer's Python API refuses bad scenes, cameras and lights in Python, naming the argument
and the bad value or index (audit rows 1, 8, 9, 12 and the camera part of 19): a mesh index out of
range segfaulted or read other memory; NaN mesh points, NaN shape sizes, a NaN camera matrix, a
focal length <= 0, near > far or a NaN near drew a blank image; an unknown projection was drawn as
a perspective one, an aperture of 0 was ignored, a zero light direction gave NaN pixels, a 3x3
camera matrix gave a numpy IndexError and up_axis "W" was framed as "Y"."""

import dataclasses

import numpy as np
import pytest

from dftl_warp.options import OptionError
from dftl_warp.render.camera import Camera, auto_frame, look_at
from dftl_warp.render.renderer import Lighting, Renderer, orbit_cameras
from dftl_warp.render.scene import BOX, CAPSULE, SPHERE, RenderScene, Shape

NAN, INF = float("nan"), float("inf")
PTS = np.array([[0.0, 0.0, 0.0], [0.0, -0.5, 0.1], [0.1, -1.0, 0.0]])
QUAD = np.array([[-1.0, -1.2, -1.0], [1.0, -1.2, -1.0], [1.0, -1.2, 1.0], [-1.0, -1.2, 1.0]])


def renderer(**kw):
    return Renderer(32, 24, spp=1, threads=1, **kw)


def camera(**kw):
    return Camera(world_from_camera=look_at([0, -0.5, 4], [0, -0.5, 0], [0, 1, 0]), **kw)


# -- mesh --------------------------------------------------------------------------------------

@pytest.mark.parametrize("index", [100000, 4, 7, -5])
def test_a_mesh_index_out_of_range_is_refused_naming_it(index):
    tris = np.array([[0, 1, 2], [0, 2, index]])
    message = rf"mesh_triangles\[1\]\[2\] = {index}: out of range for 4 mesh_points"
    with pytest.raises(ValueError, match=message):
        RenderScene.from_strands(PTS, [3], 0.02, mesh_points=QUAD, mesh_triangles=tris)
    built = RenderScene.from_strands(PTS, [3], 0.02)   # built by hand: refused before the kernels
    built.mesh_points, built.mesh_triangles = QUAD, tris
    with pytest.raises(ValueError, match=message):
        renderer().render(built, camera())


def test_bad_mesh_arrays_are_refused():
    with pytest.raises(ValueError, match=r"mesh_points\[2\] is not finite"):
        RenderScene.from_strands(PTS, [3], 0.02, mesh_points=np.where(np.arange(4)[:, None] == 2, NAN, QUAD),
                                 mesh_triangles=[[0, 1, 2]])
    with pytest.raises(ValueError, match=r"mesh_triangles of shape \(2, 2\): expected \(K, 3\)"):
        RenderScene.from_strands(PTS, [3], 0.02, mesh_points=QUAD, mesh_triangles=[[0, 1], [2, 3]])
    with pytest.raises(ValueError, match="mesh_triangles must be whole numbers"):
        RenderScene.from_strands(PTS, [3], 0.02, mesh_points=QUAD, mesh_triangles=[[0, 1, 2.5]])
    with pytest.raises(ValueError, match=r"mesh_points of shape \(4, 2\): expected \(M, 3\)"):
        RenderScene.from_strands(PTS, [3], 0.02, mesh_points=QUAD[:, :2], mesh_triangles=[[0, 1, 2]])


def test_a_nan_mesh_point_no_longer_blanks_the_image():
    scene = RenderScene.from_strands(PTS, [3], 0.02)
    scene.mesh_points = QUAD.copy()
    scene.mesh_points[3, 1] = NAN
    scene.mesh_triangles = np.array([[0, 1, 2], [0, 2, 3]])
    with pytest.raises(ValueError, match=r"mesh_points\[3\] is not finite"):
        renderer().render(scene, camera())


# -- shapes ------------------------------------------------------------------------------------

@pytest.mark.parametrize("shape, message", [
    (Shape(SPHERE, np.eye(4), (NAN, 0, 0)), r"shapes\[0\] params\[0\] = nan: not finite"),
    (Shape(SPHERE, np.eye(4), (-0.1, 0, 0)), r"shapes\[0\] params\[0\] = -0.1: a sphere size must be >= 0"),
    (Shape(CAPSULE, np.eye(4), (-0.1, 0.2, 1)), r"shapes\[0\] params\[0\] = -0.1: a capsule size must be >= 0"),
    (Shape(CAPSULE, np.eye(4), (0.1, 0.2, 3)), r"shapes\[0\] params\[2\] = 3: a capsule axis must be 0, 1 or 2"),
    (Shape(BOX, np.eye(4), (0.1, INF, 0.1)), r"shapes\[0\] params\[1\] = inf: not finite"),
    (Shape(BOX, np.eye(4), (0.1, 0.1)), r"shapes\[0\] params of 2 numbers: expected 3"),
    (Shape(7, np.eye(4), (1, 0, 0)), r"shapes\[0\] kind 7: must be 0 \(sphere\), 1 \(capsule\) or 2 \(box\)"),
    (Shape(SPHERE, np.full((4, 4), NAN), (0.1, 0, 0)), r"shapes\[0\] world_from_local\[0\]\[0\] = nan: not finite"),
    (Shape(SPHERE, np.eye(3), (0.1, 0, 0)), r"shapes\[0\] world_from_local of shape \(3, 3\): expected a 4x4"),
])
def test_a_bad_shape_is_refused_naming_it(shape, message):
    with pytest.raises(ValueError, match=message):
        RenderScene.from_strands(PTS, [3], 0.02, shapes=[shape])
    built = RenderScene(shapes=[shape])
    with pytest.raises(ValueError, match=message):
        renderer().render(built, camera())


def test_good_shapes_and_mesh_still_render():
    shapes = [Shape(SPHERE, np.eye(4), (0.2, 0, 0)), Shape(CAPSULE, np.eye(4), (0.1, 0.2, 1.0)),
              Shape(BOX, np.eye(4), (0.1, 0.1, 0.1)), Shape(SPHERE, np.eye(4), (0.0, 0, 0))]
    scene = RenderScene.from_strands(PTS, [3], 0.02, shapes=shapes, mesh_points=QUAD,
                                     mesh_triangles=np.array([[0, 1, 2], [0, 2, 3]], dtype=np.int32))
    image = renderer().render(scene, camera())
    assert np.isfinite(image).all() and image[..., 3].sum() > 0


# -- up axis -----------------------------------------------------------------------------------

@pytest.mark.parametrize("axis", ["W", "x", "", None])
def test_an_unknown_up_axis_is_refused(axis):
    with pytest.raises(OptionError, match=rf"up_axis {axis!r}: must be 'Y' or 'Z'"):   # one line for the CLI
        RenderScene.from_strands(PTS, [3], 0.02, up_axis=axis)
    built = RenderScene.from_strands(PTS, [3], 0.02)
    built.up_axis = axis
    with pytest.raises(ValueError, match="must be 'Y' or 'Z'"):
        renderer().render(built)
    with pytest.raises(ValueError, match="must be 'Y' or 'Z'"):
        orbit_cameras(camera(), built, 2)
    with pytest.raises(ValueError, match="must be 'Y' or 'Z'"):
        auto_frame(None, 32, 24, axis)


def test_y_and_z_in_either_case_are_accepted():
    for axis in ("Y", "Z", "y", "z"):
        scene = RenderScene.from_strands(PTS, [3], 0.02, up_axis=axis)
        assert len(orbit_cameras(camera(), scene, 2)) == 2


# -- camera ------------------------------------------------------------------------------------

@pytest.mark.parametrize("field, message", [
    (dict(world_from_camera=np.full((4, 4), NAN)), r"camera world_from_camera\[0\]\[0\] = nan: not finite"),
    (dict(world_from_camera=np.eye(3)), r"camera world_from_camera of shape \(3, 3\): expected a 4x4 matrix"),
    (dict(world_from_camera="x"), r"camera world_from_camera 'x': expected a 4x4 matrix"),
    (dict(focal_length=0.0), "camera focal_length = 0: must be > 0"),
    (dict(focal_length=-50.0), "camera focal_length = -50: must be > 0"),
    (dict(focal_length=INF), "camera focal_length = inf: must be finite"),
    (dict(focal_length="50"), "camera focal_length = '50': expected a number"),
    (dict(horizontal_aperture=0.0), "camera horizontal_aperture = 0: must be > 0"),
    (dict(vertical_aperture=-1.0), "camera vertical_aperture = -1: must be > 0"),
    (dict(horizontal_aperture_offset=NAN), "camera horizontal_aperture_offset = nan: not a number"),
    (dict(near=10.0, far=1.0), "camera near = 10, far = 1: must have near < far"),
    (dict(near=NAN), "camera near = nan: not a number"),
    (dict(near=-1.0), "camera near = -1: must be finite and >= 0"),
    (dict(far=NAN), "camera far = nan: not a number"),
    (dict(projection="fisheye"), "camera projection 'fisheye': must be 'perspective' or 'orthographic'"),
])
def test_a_bad_camera_is_refused_when_built_and_when_rendered(field, message):
    good = camera()
    with pytest.raises(OptionError, match=message):
        dataclasses.replace(good, **field)
    with pytest.raises(ValueError, match=message):   # an OptionError is a ValueError
        Camera(**{"world_from_camera": good.world_from_camera, **field})
    for name, value in field.items():   # a field set after the camera was built
        setattr(good, name, value)
    scene = RenderScene.from_strands(PTS, [3], 0.02)
    with pytest.raises(OptionError, match=message):
        renderer().render(scene, good)


def test_a_camera_names_its_path_and_good_cameras_render():
    with pytest.raises(OptionError, match="camera /cam: focal_length = 0: must be > 0"):
        camera(focal_length=0.0, path="/cam")
    scene = RenderScene.from_strands(PTS, [3], 0.02)
    r = renderer()
    for cam in (camera(near=0.0, far=INF), camera(projection="orthographic", horizontal_aperture=20.0,
                                                   vertical_aperture=15.0)):
        assert r.render(scene, cam)[..., 3].sum() > 0 and r.hair_visible


# -- lighting ----------------------------------------------------------------------------------

@pytest.mark.parametrize("field, message", [
    (dict(key_dir=(0, 0, 0)), r"lighting key_dir \(0, 0, 0\): must be a nonzero vector"),
    (dict(fill_dir=(0.0, 0.0, 0.0)), r"lighting fill_dir \(0, 0, 0\): must be a nonzero vector"),
    (dict(key_dir=(NAN, 1, 0)), r"lighting key_dir \(nan, 1, 0\): must be finite"),
    (dict(key_dir=(1, 0)), r"lighting key_dir \(1, 0\): expected 3 numbers"),
    (dict(fill_dir="up"), r"lighting fill_dir 'up': expected 3 numbers"),
    (dict(key_color=(1, -1, 1)), r"lighting key_color \(1, -1, 1\): must not be negative"),
    (dict(ambient=(INF, 0, 0)), r"lighting ambient \(inf, 0, 0\): must be finite"),
    (dict(hair_shadow_transmittance=1.5), "lighting hair_shadow_transmittance = 1.5: must be from 0 to 1"),
    (dict(roughness=NAN), "lighting roughness = nan: expected a finite number"),
    (dict(roughness=-0.1), "lighting roughness = -0.1: must be >= 0"),
])
def test_bad_lighting_is_refused(field, message):
    with pytest.raises(OptionError, match=message):
        Lighting(**field)
    light = Lighting()
    r = renderer(lighting=light)
    for name, value in field.items():   # set after the renderer took it
        setattr(light, name, value)
    with pytest.raises(OptionError, match=message):
        r.render(RenderScene.from_strands(PTS, [3], 0.02), camera())


def test_a_nonzero_light_direction_of_any_length_renders_finite_pixels():
    r = renderer(lighting=Lighting(key_dir=(0, 5, 0), fill_dir=(1e-3, 0, 0)))
    image = r.render(RenderScene.from_strands(PTS, [3], 0.02), camera())
    assert np.isfinite(image).all() and image[..., 3].sum() > 0


# -- one number check, one matrix check ------------------------------------------------------------

@pytest.mark.parametrize("make, message", [
    # numpy scalars and arrays were shown as Python's repr: 'np.float64(nan)', 'array([50.])'
    (lambda: Lighting(roughness=np.float64(NAN)), "lighting roughness = nan: expected a finite number"),
    (lambda: Lighting(hair_shadow_transmittance="x"), "lighting hair_shadow_transmittance = 'x': expected a finite number"),
    (lambda: camera(focal_length=np.array([50.0])), r"camera focal_length = \[50\]: expected a number"),
    (lambda: camera(near=np.float32(NAN)), "camera near = nan: not a number"),
    # a shape's matrix of strings said 'world_from_local must be numbers', a camera's named the value
    (lambda: RenderScene(shapes=[Shape(SPHERE, "x", (0.1, 0, 0))]).check(),
     r"shapes\[0\] world_from_local 'x': expected a 4x4 matrix of numbers"),
    (lambda: RenderScene(shapes=[Shape(SPHERE, np.eye(3), (0.1, 0, 0))]).check(),
     r"shapes\[0\] world_from_local of shape \(3, 3\): expected a 4x4 matrix of numbers"),
])
def test_renderer_fields_are_checked_in_the_usd_readers_words(make, message):
    """The camera's and the lighting's number checks are the USD reader's (usd/values.py number:
    plain values, one line); a camera's and a shape's 4x4 matrix go through one check."""
    with pytest.raises(ValueError, match=f"^{message}$"):
        make()
