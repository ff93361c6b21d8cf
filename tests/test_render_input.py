"""Bad render input: the numpy API (``RenderScene.from_strands``, ``Renderer.render``) raises
ValueError naming the index; ``dftl-warp render`` refuses invalid cubic curves, malformed layers,
bad ``--fps`` and fractional frames in '#' patterns with one line and exit 2, writing nothing."""

import numpy as np
import pytest

from dftl_warp import RenderScene, Renderer, cli
from dftl_warp.render import image
from dftl_warp.render.camera import Camera
from render_util import add_camera, add_curves, new_stage

PTS = np.array([[0.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, -2.0, 0.0]])


# -- Python API -----------------------------------------------------------------------------------


@pytest.mark.parametrize("points, counts, widths, message", [
    (PTS, [100000], 0.1, "vertex counts sum to 100000 but there are 3 points"),
    (PTS, [4], 0.1, "vertex counts sum to 4 but there are 3 points"),
    (PTS, [2, -1, 2], 0.1, "strand 1 has -1 vertices"),
    (PTS, [1.5, 1.5], 0.1, "counts must be a 1-D array of integers"),
    (np.zeros(7), [2], 0.1, "points must have shape (N, 3)"),
    (np.where(np.arange(9).reshape(3, 3) == 4, np.nan, PTS), [3], 0.1, "point 1 is not finite"),
    (PTS, [3], [0.1, -0.1, 0.1], "widths[1] is negative"),
    (PTS, [3], -0.1, "widths[0] is negative"),
    (PTS, [3], [0.1, 0.1, np.inf], "widths[2] is not finite"),
    (PTS, [3], [0.1, 0.1], "2 widths for 1 strand of 3 points: expected one, one per strand or one per point"),
    (PTS, [2, 1], [0.1, -0.2], "widths[2] is negative"),  # per strand, expanded per point
])
def test_from_strands_rejects_bad_arrays(points, counts, widths, message):
    with pytest.raises(ValueError) as e:
        RenderScene.from_strands(points, counts, widths)
    assert message in str(e.value)


def test_from_strands_rejects_bad_colors():
    with pytest.raises(ValueError, match=r"colors\[1\] is not finite"):
        RenderScene.from_strands(PTS, [3], 0.1, [[1, 0, 0], [0, np.nan, 0], [0, 0, 1]])
    with pytest.raises(ValueError, match="colors of shape"):
        RenderScene.from_strands(PTS, [3], 0.1, [1, 0])
    with pytest.raises(ValueError, match="2 colours for 1 strand of 3 vertices"):
        RenderScene.from_strands(PTS, [3], 0.1, [[1, 0, 0], [0, 1, 0]])


def test_from_strands_accepts_every_width_layout_and_empty_strands():
    for widths, radii in ((0.2, [0.1] * 3), ([0.2, 0.4], [0.1, 0.1, 0.2]), ([0.2, 0.4, 0.6], [0.1, 0.2, 0.3])):
        counts = [2, 1] if len(np.atleast_1d(widths)) == 2 else [3]
        s = RenderScene.from_strands(PTS, counts, widths)
        assert np.allclose(s.radii, radii)
    s = RenderScene.from_strands(PTS, np.array([0, 3, 0]), None)  # a strand of 0 vertices draws nothing
    assert s.segment_count == 2 and s.radii.shape == (3,) and (s.radii > 0).all()
    s = RenderScene.from_strands(PTS, np.array([3.0]), 0.0)  # whole float counts, zero width
    assert s.curve_vertex_counts.dtype == np.int64 and s.segment_count == 2


def test_renderer_refuses_a_scene_whose_arrays_do_not_fit():
    """A RenderScene built by hand is checked before the kernels index its arrays."""
    world_from_camera = np.eye(4)
    world_from_camera[:3, 3] = (0.0, -1.0, 5.0)  # column vectors: looking down -Z at the strand
    cam = Camera(world_from_camera=world_from_camera, path="/c")
    bad = RenderScene(points=PTS, curve_vertex_counts=np.array([100000]), radii=np.full(3, 0.1),
                      colors=np.zeros((3, 3)))
    r = Renderer(8, 8, spp=1, device="cpu")
    with pytest.raises(ValueError, match="vertex counts sum to 100000 but there are 3 points"):
        r.render(bad, cam)
    bad = RenderScene(points=PTS, curve_vertex_counts=np.array([3]), radii=np.full(2, 0.1), colors=np.zeros((3, 3)))
    with pytest.raises(ValueError, match="2 radii for 3 points"):
        r.render(bad, cam)
    bad = RenderScene(points=PTS, curve_vertex_counts=np.array([3]), radii=np.full(3, 0.1), colors=np.zeros((2, 3)))
    with pytest.raises(ValueError, match=r"colors of shape \(2, 3\) for 3 points"):
        r.render(bad, cam)
    good = RenderScene.from_strands(PTS, [3], 0.5)
    assert r.render(good, cam)[..., 3].sum() > 0


def test_frame_path_and_write_video_check_their_arguments(tmp_path):
    assert image.frame_path("a.####.png", 12) == "a.0012.png"
    assert image.frame_path("a.####.png", 3.0000000001) == "a.0003.png"
    assert image.frame_path("a.png", 1.5) == "a.png"
    with pytest.raises(ValueError, match="frame 1.5 is not a whole number"):
        image.frame_path("a.####.png", 1.5)
    frames = [np.zeros((4, 4, 4), np.uint8)]
    for fps in (0, -5, float("nan"), float("inf")):
        with pytest.raises(ValueError, match="must be a positive, finite number"):
            image.write_video(tmp_path / "v.gif", frames, fps=fps)
    assert list(tmp_path.iterdir()) == []


# -- the command ----------------------------------------------------------------------------------


def render(*args):
    return cli.main(["render", *map(str, args), "-q"])


def one_error(capsys, *fragments):
    err = capsys.readouterr().err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("dftl-warp: error: "), err
    assert "Traceback" not in err and "pxrInternal" not in err and "Error in '" not in err
    for f in fragments:
        assert f in lines[0], err
    return lines[0]


@pytest.fixture
def groom(tmp_path):
    path = tmp_path / "groom.usda"
    stage = new_stage(path)
    stage.SetStartTimeCode(1)
    stage.SetEndTimeCode(3)
    add_camera(stage, translate=(0, 0.5, 3))
    strands = [np.array([[x, 0, 0], [x, 0.5, 0.1], [x + 0.1, 1.0, 0]]) for x in (-0.2, 0.0, 0.2)]
    for f in (1, 2, 3):
        add_curves(stage, "/hair", [s + [0.1 * f, 0, 0] for s in strands], widths=[0.03], time=f)
    stage.Save()
    return path


def cubic_stage(path, counts, basis="bezier", wrap="nonperiodic"):
    stage = new_stage(path)
    add_camera(stage, translate=(0, -1, 6))
    strands = [np.column_stack([np.full(n, float(k)), -np.arange(n, dtype=float), np.zeros(n)])
               for k, n in enumerate(counts)]
    c = add_curves(stage, "/W/H", strands, widths=[0.05], curve_type="cubic")
    c.CreateBasisAttr(basis)
    c.CreateWrapAttr(wrap)
    stage.Save()
    return path


@pytest.mark.parametrize("counts, basis, wrap, message", [
    ([2, 4], "bezier", "nonperiodic",
     "curveVertexCounts[0] = 2: a nonperiodic cubic bezier curve needs 3n + 1"),
    ([4, 5], "bezier", "nonperiodic", "curveVertexCounts[1] = 5: a nonperiodic cubic bezier"),
    ([3, 3], "bezier", "nonperiodic", "curveVertexCounts[0] = 3"),
    ([4, 3], "bspline", "nonperiodic", "curveVertexCounts[1] = 3: a nonperiodic cubic bspline curve needs at least 4"),
    ([1, 4], "catmullRom", "pinned", "curveVertexCounts[0] = 1: a pinned cubic catmullRom curve needs at least 2"),
])
def test_invalid_cubic_vertex_counts_are_refused_as_simulate_refuses_them(tmp_path, capsys, counts, basis, wrap,
                                                                          message):
    src = cubic_stage(tmp_path / "cubic.usda", counts, basis, wrap)
    out = tmp_path / "out.png"
    assert render(src, "--resolution", "16x16", "--spp", 1, "-o", out) == 2
    line = one_error(capsys, f"{src}: /W/H: {message}")
    assert not out.exists()
    # the simulation's reader gives the same message
    assert cli.main(["info", str(src)]) == 2
    assert capsys.readouterr().err.strip().splitlines() == [line]


@pytest.mark.parametrize("counts, basis, message", [
    ([6, 7], "bezier", "curveVertexCounts[1] = 7: a periodic cubic bezier curve needs 3n"),
    ([2, 4], "bspline", "curveVertexCounts[0] = 2: a periodic cubic bspline curve needs at least 3"),
])
def test_periodic_cubic_curves_with_unusable_counts_are_refused_not_shortened(tmp_path, capsys, counts, basis,
                                                                              message):
    """The renderer draws closed curves (simulate refuses them: a hair needs a free tip); a count
    its basis cannot close was cut to whole spans without a word."""
    src = cubic_stage(tmp_path / "cubic.usda", counts, basis, "periodic")
    out = tmp_path / "out.png"
    assert render(src, "--resolution", "16x16", "--spp", 1, "-o", out) == 2
    one_error(capsys, f"{src}: /W/H: {message}")
    assert not out.exists()


def test_valid_cubic_curves_still_render(tmp_path):
    src = cubic_stage(tmp_path / "ok.usda", [4, 7])
    out = tmp_path / "ok.png"
    assert render(src, "--resolution", "16x16", "--spp", 1, "-o", out) == 0
    assert image.read_png(out)[..., 3].sum() > 0


@pytest.mark.parametrize("text, fragment", [
    ("", "empty.usda: cannot open as a USD stage: "),
    ("not usd at all\n", "empty.usda: cannot open as a USD stage: "),
    ("#usda 1.0\ndef X \"a\" {\n", "empty.usda:3:1: syntax error: "),
])
def test_malformed_layer_is_one_line_like_simulate(tmp_path, capsys, text, fragment):
    src = tmp_path / "empty.usda"
    src.write_text(text)
    out = tmp_path / "out.png"
    assert render(src, "-o", out) == 2
    line = one_error(capsys, fragment)
    assert not out.exists()
    assert cli.main(["simulate", str(src), "-o", str(tmp_path / "sim.usdc")]) == 2
    assert capsys.readouterr().err.strip().splitlines() == [line]


@pytest.mark.parametrize("fps", ["0", "-5", "nan", "inf"])
def test_bad_fps_is_refused_before_rendering(groom, tmp_path, capsys, fps):
    out = tmp_path / "v.gif"
    assert render(groom, "--start", 1, "--end", 3, "--fps", fps, "--resolution", "8x8", "--spp", 1, "-o", out) == 2
    one_error(capsys, f"--fps {float(fps):g}: must be a positive, finite number")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["groom.usda"]


def test_fps_with_an_image_output_warns_once(groom, tmp_path, capsys):
    pattern = tmp_path / "f" / "p.####.png"
    assert render(groom, "--start", 1, "--end", 2, "--fps", 12, "--resolution", "8x8", "--spp", 1, "-o", pattern) == 0
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [f"dftl-warp: warning: --fps applies only to a video output (.mp4, .gif, .mov, .webm): "
                   f"ignored for -o {pattern}"]
    assert sorted(p.name for p in pattern.parent.iterdir()) == ["p.0001.png", "p.0002.png"]
    gif = tmp_path / "v.gif"
    assert render(groom, "--start", 1, "--end", 2, "--fps", 12, "--resolution", "8x8", "--spp", 1, "-o", gif) == 0
    assert capsys.readouterr().err == ""
    import imageio.v3 as iio

    assert iio.immeta(gif, index=0).get("duration") == pytest.approx(1000 / 12, abs=10)  # GIF: centiseconds


@pytest.mark.parametrize("args, frame", [
    (["--start", 1, "--end", 2, "--step", 0.5], "frame 1.5 (--step 0.5) is not a whole number"),
    (["--start", 1.5, "--end", 2.5], "frame 1.5 (--step 1) is not a whole number"),
    (["--frame", 1.5], "frame 1.5 is not a whole number"),
])
def test_fractional_frames_in_a_pattern_are_refused(groom, tmp_path, capsys, args, frame):
    pattern = tmp_path / "f" / "half.####.png"
    assert render(groom, *args, "--resolution", "8x8", "--spp", 1, "-o", pattern) == 2
    one_error(capsys, f"-o {pattern}: {frame}: a '#' pattern is numbered by frame")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["groom.usda"]


def test_fractional_frames_into_a_video_or_sheet_are_fine(groom, tmp_path):
    sheet = tmp_path / "sheet.png"
    assert render(groom, "--start", 1, "--end", 2, "--step", 0.5, "--contact-sheet", "--resolution", "8x8",
                  "--spp", 1, "-o", sheet) == 0
    assert image.read_png(sheet).shape == (2 * 8 + 4, 2 * 8 + 4, 4)  # 3 frames on a 2x2 grid


def test_a_frame_that_fails_leaves_no_frames_of_the_sequence(groom, tmp_path, capsys):
    """Frame 3 has nothing visible: the render stops with one line, and the frames rendered before
    it are not left behind (nor a frame of an earlier render of the same names overwritten)."""
    from pxr import Usd, UsdGeom

    stage = Usd.Stage.Open(str(groom))
    visibility = UsdGeom.Imageable(stage.GetPrimAtPath("/hair")).GetVisibilityAttr()
    for t, value in ((1, "inherited"), (2, "inherited"), (3, "invisible")):
        visibility.Set(value, t)
    stage.Save()
    out = tmp_path / "frames"
    out.mkdir()
    (out / "hair.0001.png").write_bytes(b"an earlier render")
    assert render(groom, "--start", 1, "--end", 3, "-o", out / "hair.####.png", "--resolution", "32x24") == 2
    one_error(capsys, "nothing to render at frame 3")
    assert sorted(p.name for p in out.iterdir()) == ["hair.0001.png"]
    assert (out / "hair.0001.png").read_bytes() == b"an earlier render"
    # and the whole sequence, once every frame renders
    visibility.Set("inherited", 3)
    stage.Save()
    assert render(groom, "--start", 1, "--end", 3, "-o", out / "hair.####.png", "--resolution", "32x24") == 0
    assert sorted(p.name for p in out.iterdir()) == ["hair.0001.png", "hair.0002.png", "hair.0003.png"]


def test_a_camera_scaled_to_nothing_is_one_line_not_a_blank_image(tmp_path, capsys):
    """A zero scale leaves the camera no view direction: the image came out blank, exit 0, with
    numpy's divide warning on the terminal."""
    from pxr import Gf

    path = tmp_path / "flat_cam.usda"
    stage = new_stage(path)
    cam = add_camera(stage, translate=(0, 0.5, 3))
    cam.AddScaleOp().Set(Gf.Vec3f(0.0, 0.0, 0.0))
    add_curves(stage, "/hair", [np.array([[0.0, 0, 0], [0.0, 0.5, 0.1], [0.1, 1.0, 0]])], widths=[0.03])
    stage.Save()
    out = tmp_path / "c.png"
    assert render(path, "--resolution", "16x12", "--spp", 1, "-o", out) == 2
    one_error(capsys, f"{path}: /cam: the camera's transform is degenerate")
    assert not out.exists()


# -- what the command and the Renderer refuse or warn about -----------------------------------------


def test_a_camera_that_sees_no_strand_warns_once_naming_it_and_the_frames(tmp_path, capsys):
    """The camera turns away from the hair at frame 3: the images are written, and one line names the
    camera and the frame (a blank image came out without a word)."""
    from pxr import Gf, UsdGeom

    path = tmp_path / "away.usda"
    stage = new_stage(path)
    stage.SetStartTimeCode(1)
    stage.SetEndTimeCode(3)
    cam = UsdGeom.Camera.Define(stage, "/cam")
    cam.AddTranslateOp().Set(Gf.Vec3d(0, 0.5, 3))
    turn = cam.AddRotateYOp()   # about the camera's own position
    for t, angle in ((1, 0.0), (2, 0.0), (3, 180.0)):
        turn.Set(angle, t)
    cam.CreateClippingRangeAttr(Gf.Vec2f(0.01, 100))
    add_curves(stage, "/hair", [np.array([[x, 0, 0], [x, 0.5, 0.1], [x, 1.0, 0]]) for x in (-0.2, 0.0, 0.2)],
               widths=[0.05])
    stage.Save()
    sheet = tmp_path / "sheet.png"
    assert render(path, "--start", 1, "--end", 3, "--contact-sheet", "--resolution", "24x16", "--spp", 2, "-o", sheet) == 0
    assert capsys.readouterr().err.strip().splitlines() == [
        "dftl-warp: warning: camera /cam sees no strand at frame 3 (1 of 3 images): no strand sample lands in the "
        "image (it looks away from the hair, or the hair is outside its clipping range, hidden behind geometry or "
        "smaller in the image than the spacing of --spp 2 samples (--min-pixel-width 1 widens strands to 1 pixel, "
        "it does not lengthen them))"]
    alpha = image.read_png(sheet)[..., 3]   # 3 frames on a 2 x 2 grid of 24 x 16 tiles, 4 pixels apart
    assert alpha[:16, :24].sum() > 0 and alpha[:16, 28:].sum() > 0 and alpha[20:, :24].sum() == 0
    out = tmp_path / "one.png"
    assert render(path, "--frame", 3, "--resolution", "24x16", "--spp", 2, "-o", out) == 0
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "camera /cam sees no strand at frame 3: no strand sample" in err, err
    assert image.read_png(out)[..., 3].sum() == 0
    assert render(path, "--frame", 1, "--resolution", "24x16", "--spp", 2, "-o", out) == 0
    assert capsys.readouterr().err == ""   # the camera sees the hair: nothing to say
    # a turntable names its views as its pattern numbers them, from 0
    assert render(path, "--turntable", 2, "--frame", 3, "--resolution", "24x16", "--spp", 2,
                  "-o", tmp_path / "t" / "view.#.png") == 0
    err = capsys.readouterr().err
    assert "camera /cam sees no strand in turntable views 0, 1 (2 of 2 images): no strand sample" in err, err
    assert sorted(p.name for p in (tmp_path / "t").iterdir()) == ["view.0.png", "view.1.png"]


def test_the_no_strand_warning_says_what_min_pixel_width_does(tmp_path, capsys):
    """Hair 10 um wide in a 24 x 16 image: with the default --min-pixel-width 1 it is drawn and seen
    (the warning blamed 'too thin for --spp 1', which did not apply); with 0 it is too thin, and
    the warning says so. A strand shorter than a pixel is missed however wide it is drawn."""
    def stage(name, strands):
        s = new_stage(tmp_path / name)
        add_camera(s, translate=(0, 0.5, 3))
        add_curves(s, "/hair", strands, widths=[1e-5])
        s.Save()
        return tmp_path / name

    thin = stage("thin.usda", [np.array([[x, 0, 0], [x, 0.5, 0.1], [x, 1.0, 0]]) for x in (-0.2, 0.0, 0.2)])
    dot = stage("dot.usda", [np.array([[0, 0.5, 0], [0, 0.5001, 0]])])
    out = tmp_path / "o.png"
    warning = "dftl-warp: warning: camera /cam sees no strand at the stage's default time: no strand sample lands"
    assert render(thin, "--resolution", "24x16", "--spp", 1, "-o", out) == 0
    assert capsys.readouterr().err == ""
    assert render(thin, "--resolution", "24x16", "--spp", 1, "--min-pixel-width", 0, "-o", out) == 0
    err = capsys.readouterr().err
    assert err.startswith(warning) and err.endswith(
        "hidden behind geometry or too thin for --spp 1 (--min-pixel-width 0 draws true widths; a width of 1 draws "
        "them at least a pixel wide))\n"), err
    assert render(dot, "--resolution", "24x16", "--spp", 1, "-o", out) == 0
    err = capsys.readouterr().err
    assert err.startswith(warning) and err.endswith(
        "hidden behind geometry or smaller in the image than the spacing of --spp 1 samples (--min-pixel-width 1 "
        "widens strands to 1 pixel, it does not lengthen them))\n"), err


def test_renderer_says_whether_the_image_shows_a_strand():
    from dftl_warp.render.camera import look_at

    scene = RenderScene.from_strands(PTS, [3], 0.1)
    r = Renderer(16, 12, spp=1)
    assert r.hair_visible is None
    r.render(scene)
    assert r.hair_visible is True
    away = Camera(world_from_camera=look_at([0, -1, 5], [0, -1, 10], [0, 1, 0]))
    assert r.render(scene, away)[..., 3].sum() == 0 and r.hair_visible is False
    # hidden behind a sphere: the image is not blank, but no strand is seen
    from dftl_warp.render.scene import Shape

    hidden = RenderScene.from_strands(PTS, [3], 0.1)
    hidden.shapes.append(Shape(kind=0, world_from_local=np.diag([5.0, 5.0, 5.0, 1.0]), params=(1.0, 0.0, 0.0)))
    front = Camera(world_from_camera=look_at([0, -1, 20], [0, -1, 0], [0, 1, 0]))
    assert r.render(hidden, front)[..., 3].sum() > 0 and r.hair_visible is False


@pytest.mark.parametrize("args, kwargs, error, message", [
    ((8.5,), {}, ValueError, "width 8.5: expected a whole number"),
    ((8, 6.7), {}, ValueError, "height 6.7: expected a whole number"),
    (("8",), {}, ValueError, "width '8': expected a whole number"),
    ((True, 8), {}, ValueError, "width True: expected a whole number"),
    ((0, 8), {}, ValueError, "width 0: must be at least 1"),
    ((20000, 8), {}, ValueError, "width 20000: must be at most 16384"),
    ((8, 8), {"spp": 2.5}, ValueError, "spp 2.5: expected a whole number"),
    ((8, 8), {"spp": float("nan")}, ValueError, "spp nan: expected a whole number"),
    ((8, 8), {"spp": 5000}, ValueError, "spp 5000: must be at most 4096"),
    ((8, 8), {"seed": 1.5}, ValueError, "seed 1.5: expected a whole number"),
    ((8, 8), {"threads": 0}, ValueError, "threads 0: must be at least 1"),
    ((8, 8), {"threads": 2.5}, ValueError, "threads 2.5: expected a whole number"),
    ((8, 8), {"shading": "phong"}, ValueError, "shading 'phong': choose one of marschner, kajiya-kay"),
    ((8, 8), {"conform": "stretch"}, ValueError, "conform 'stretch': choose one of expandAperture"),
    ((8, 8), {"device": "cuda:99"}, ValueError, "device 'cuda:99' is not available here"),
    ((8, 8), {"lighting": 3}, TypeError, "lighting must be a Lighting or None, got int"),
])
def test_renderer_refuses_bad_arguments_instead_of_truncating_them(args, kwargs, error, message):
    with pytest.raises(error) as e:
        Renderer(*args, **kwargs)
    assert message in str(e.value)


def test_renderer_takes_whole_numbers_of_any_type_and_refuses_a_wrong_scene_or_camera():
    r = Renderer(np.int64(8), 6.0, spp=np.int32(2), threads=1)
    assert (r.width, r.height, r.spp, r.threads) == (8, 6, 2, 1) and type(r.height) is int
    with pytest.raises(TypeError, match="scene must be a RenderScene, got ndarray"):
        r.render(PTS)
    with pytest.raises(TypeError, match="camera must be a Camera or None, got str"):
        r.render(RenderScene.from_strands(PTS, [3], 0.1), "/cam")


@pytest.fixture
def static_groom(tmp_path):
    """A stage without a time range or time samples."""
    path = tmp_path / "static.usda"
    stage = new_stage(path)
    add_camera(stage, translate=(0, 0.5, 3))
    add_curves(stage, "/hair", [np.array([[0.0, 0, 0], [0.0, 0.5, 0.1], [0.1, 1.0, 0]])], widths=[0.03])
    stage.Save()
    return path


@pytest.mark.parametrize("args, message", [
    (["--frame", "nan"], "--frame nan: expected a finite time code"),
    (["--frame", "inf"], "--frame inf: expected a finite time code"),
    (["--frame=-inf"], "--frame -inf: expected a finite time code"),
    (["--start", "nan", "--end", "3"], "--start nan: expected a finite time code"),
    (["--start", "1", "--end", "inf"], "--end inf: expected a finite time code"),
    (["--start", "1", "--end", "3", "--step", "nan"], "--step nan: expected a finite time code"),
    (["--start", "1", "--end", "3", "--step", "inf"], "--step inf: expected a finite time code"),
    (["--start", "1", "--end", "1e12"], "--start 1 --end 1e+12 --step 1: 1e+12 frames; one render makes at most 100000"),
    (["--start", "1", "--end", "2", "--step", "1e-320"], ": inf frames; one render makes at most 100000"),
    (["--turntable", "1000000"], "--turntable 1000000: must be at most 100000"),
    (["--spp", "5000"], "--spp 5000: must be at most 4096"),
    (["--resolution", "20000x10"], "--resolution '20000x10': width and height must be between 1 and 16384"),
])
def test_non_finite_frames_and_absurd_counts_are_one_line(static_groom, tmp_path, capsys, args, message):
    """``--frame nan`` on a static stage rendered the default time, exit 0; ``--start nan`` was a
    traceback; ``--end 1e12`` or ``--turntable 1000000`` made a list of a trillion cameras."""
    out = tmp_path / "out.png"
    assert render(static_groom, *args, "-o", out) == 2
    one_error(capsys, message)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["static.usda"]


@pytest.mark.parametrize("args, message", [
    (["-o", ""], "argument -o/--output: empty path: give the image to write, such as out/hair.png"),
    (["-o", "  "], "argument -o/--output: empty path"),
    (["--camera", "", "-o", "x.png"], "argument --camera: empty path: give a UsdGeom.Camera prim path, or auto"),
])
def test_an_empty_output_or_camera_is_one_line(static_groom, capsys, args, message):
    with pytest.raises(SystemExit) as e:
        render(static_groom, *args)
    assert e.value.code == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and message in lines[0], lines


def test_a_turntable_of_a_fractional_frame_into_a_pattern_renders(groom, tmp_path):
    """The views are numbered 0, 1, ...: the pattern was checked with the frame (1.5) instead, a
    ValueError traceback."""
    out = tmp_path / "tt" / "view.##.png"
    assert render(groom, "--turntable", 2, "--frame", 1.5, "--resolution", "8x8", "--spp", 1, "-o", out) == 0
    assert sorted(p.name for p in out.parent.iterdir()) == ["view.00.png", "view.01.png"]


def _hand_written(path, counts_decl, extra=""):
    """A hand-written stage with a camera and /World/Hair: linear curves of 5 points."""
    path.write_text(f'''#usda 1.0
(
    upAxis = "Y"
)
def Camera "cam"
{{
    double3 xformOp:translate = (0.05, -0.1, 2)
    uniform token[] xformOpOrder = ["xformOp:translate"]
}}
def Xform "World"
{{
    def BasisCurves "Hair"
    {{
        uniform token type = "linear"
        {counts_decl}
        point3f[] points = [(0, 0, 0), (0, -0.1, 0), (0.1, 0, 0), (0.1, -0.1, 0), (0.1, -0.2, 0)]
        {extra}
    }}
}}
''')
    return path


@pytest.mark.parametrize("counts, extra, message", [
    ("int[] curveVertexCounts = [2, 3]", 'string[] widths = ["a"] (interpolation = "constant")',
     "widths = ['a']: expected numbers (float[])"),
    ("int[] curveVertexCounts = [2, 3]", 'string[] primvars:widths = ["a"] (interpolation = "constant")',
     "primvars:widths = ['a']: expected numbers (float[])"),
    ("int[] curveVertexCounts = [2, 3]", 'string[] primvars:displayColor = ["a"] (interpolation = "constant")',
     "primvars:displayColor = ['a']: expected numbers (color3f[])"),
    ("int[] curveVertexCounts = [2, 3]", 'float[] primvars:displayColor = [1, 0] (interpolation = "constant")',
     "primvars:displayColor: 2 numbers are not RGB triples: expected color3f[]"),
    ("float[] curveVertexCounts = [2.5, 2.5]", "", "curveVertexCounts[0] = 2.5: expected a whole number (int[])"),
    ("int curveVertexCounts = 5", "",
     "curveVertexCounts = 5: one number, expected int[] (one count per curve, in brackets)"),
])
def test_attributes_of_the_wrong_type_are_the_simulation_readers_one_line(tmp_path, capsys, counts, extra, message):
    """``string[] widths`` crashed render with a ValueError traceback, ``float[] curveVertexCounts =
    [2.5, 2.5]`` was truncated to [2, 2] (then refused as summing to 4), and ``int curveVertexCounts
    = 5`` (no brackets) was a TypeError in render and one curve of 5 in simulate. Now render and
    info give the same line."""
    src = _hand_written(tmp_path / "in.usda", counts, extra)
    out = tmp_path / "out.png"
    assert render(src, "--resolution", "16x16", "--spp", 1, "-o", out) == 2
    line = one_error(capsys, f"{src}: /World/Hair: {message}")
    assert line.endswith(message) and not out.exists()
    assert cli.main(["info", str(src)]) == 2
    assert capsys.readouterr().err.strip().splitlines() == [line]


def test_whole_float_counts_and_a_scalar_width_still_render(tmp_path):
    src = _hand_written(tmp_path / "in.usda", "float[] curveVertexCounts = [2.0, 3.0]",
                        'float widths = 0.02 (interpolation = "constant")')
    out = tmp_path / "out.png"
    assert render(src, "--resolution", "16x16", "--spp", 1, "-o", out) == 0
    assert image.read_png(out)[..., 3].sum() > 0
