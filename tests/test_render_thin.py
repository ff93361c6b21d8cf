"""Thin strands and the minimum pixel width (``Renderer(min_pixel_width=W)``, ``--min-pixel-width``).

Real hair (40-100 um) is a fraction of a pixel wide in a preview. A strand thinner than W pixels at
its depth is drawn W pixels wide with its opacity scaled by true / drawn width. Checked against
geometry: fields of parallel strands of known width and spacing, framed so that the image holds a
whole number of periods, cover exactly width / spacing of the image (a grid of two such fields,
1 - (1 - c1)(1 - c2)); the drawn width in pixels at two depths; a strand wider than W unchanged.
"""

import numpy as np
import pytest

from dftl_warp import cli
from dftl_warp.render import Camera, Lighting, Renderer, RenderScene
from dftl_warp.render.camera import look_at
from dftl_warp.render.scene import BOX, Shape
from render_util import add_camera, add_curves, new_stage

W, H = 40, 32          # pixels; a pixel is PIXEL metres at DEPTH (perspective) or anywhere (orthographic)
PIXEL = 1.0e-3
DEPTH = 1.0


def camera(projection="perspective", width=W, height=H, depth=DEPTH):
    """Looking down -z at the plane z = 0 from z = ``depth``; a pixel is PIXEL wide at DEPTH. Narrow
    (1.1 degrees off axis at the corners): every strand of a frontal field has the same projected width."""
    m = look_at([0.0, 0.0, depth], [0.0, 0.0, 0.0], [0.0, 1.0, 0.0])
    if projection == "orthographic":   # aperture in tenths of a stage unit
        return Camera(world_from_camera=m, horizontal_aperture=10.0 * PIXEL * width,
                      vertical_aperture=10.0 * PIXEL * height, projection="orthographic", near=0.01, far=10.0)
    focal = 50.0
    return Camera(world_from_camera=m, focal_length=focal, horizontal_aperture=focal * PIXEL * width / DEPTH,
                  vertical_aperture=focal * PIXEL * height / DEPTH, near=0.01, far=10.0)


def field(count, extent, z=0.0, axis=0, length=None):
    """``count`` straight strands along ``axis`` (0: x, 1: y), evenly spaced across ``extent`` metres
    (one per period, centred in it), reaching past the image on both sides."""
    spacing = extent / count
    half = length or extent
    strands = []
    for j in range(count):
        c = -0.5 * extent + (j + 0.5) * spacing
        a, b = [[-half, c, z], [half, c, z]] if axis == 0 else [[c, -half, z], [c, half, z]]
        strands.append(np.linspace(a, b, 5))
    return np.concatenate(strands), np.full(count, 5), spacing


@pytest.mark.parametrize("projection", ["perspective", "orthographic"])
@pytest.mark.parametrize("min_width", [0.0, 1.0, 3.0])
def test_thin_parallel_strands_cover_width_over_spacing(projection, min_width):
    """10 strands of 0.25 px (0.25 mm at 1 mm a pixel) every 3.2 px: 7.8 % of the image, with or
    without the minimum width (drawn 1 or 3 px wide at opacity 0.25 or 0.083)."""
    width = 0.25 * PIXEL
    pts, counts, spacing = field(10, H * PIXEL)
    scene = RenderScene.from_strands(pts, counts, width)
    alpha = Renderer(W, H, spp=16, min_pixel_width=min_width, threads=1).render(scene, camera(projection))[..., 3]
    expected = width / spacing
    assert alpha.mean() == pytest.approx(expected, rel=0.03), (alpha.mean(), expected)
    if min_width:
        # drawn min_width px wide: no pixel is more than true / drawn covered
        assert alpha.max() <= width / (min_width * PIXEL) * (1 + 1e-5)


def test_a_grid_of_thin_strands_over_a_white_backdrop_darkens_it_by_the_covered_fraction():
    """Black strands (horizontal, 0.3 px every 3.2 px, in front; vertical, 0.2 px every 4 px, 5 cm
    behind) before a white box lit by a white ambient alone: 1 - mean brightness is the covered
    fraction 1 - (1 - c1)(1 - c2) of the two independent fields, composited front to back."""
    front, back = 0.3 * PIXEL, 0.2 * PIXEL
    p1, n1, s1 = field(10, H * PIXEL, z=0.0, axis=0)
    p2, n2, s2 = field(10, W * PIXEL * 1.05, z=-0.05, axis=1)   # 5 % farther: the same 4 px period on screen
    scene = RenderScene.from_strands(np.concatenate([p1, p2]), np.concatenate([n1, n2]),
                                     np.concatenate([np.full(len(p1), front), np.full(len(p2), back)]),
                                     colors=(0.0, 0.0, 0.0))
    scene.shapes.append(Shape(BOX, _translate(0, 0, -0.5), (1.0, 1.0, 0.1)))
    light = Lighting(key_color=(0.0, 0.0, 0.0), fill_color=(0.0, 0.0, 0.0), ambient=(1.0, 1.0, 1.0),
                     geometry_albedo=(1.0, 1.0, 1.0))
    c1, c2 = front / s1, back / s2
    expected = 1.0 - (1.0 - c1) * (1.0 - c2)
    for min_width in (0.0, 1.0, 2.0):
        img = Renderer(W, H, spp=16, lighting=light, min_pixel_width=min_width, threads=1).render(scene, camera())
        assert np.all(img[..., 3] == 1.0)   # the backdrop fills the frame
        brightness = img[..., 0] * img[..., 3]
        assert 1.0 - brightness.mean() == pytest.approx(expected, rel=0.03), (min_width, 1 - brightness.mean())


def _translate(x, y, z):
    m = np.eye(4)
    m[:3, 3] = (x, y, z)
    return m


@pytest.mark.parametrize("projection, depth", [("perspective", 1.0), ("perspective", 2.0), ("orthographic", 2.0)])
def test_the_drawn_width_is_the_minimum_in_pixels_at_the_strands_depth(projection, depth):
    """One horizontal strand of 0.25 mm on the middle row (W x H odd: the axis is a row's centre),
    seen from 1 m (0.25 px) and 2 m (0.125 px; orthographic: 0.25 px anywhere). Drawn 2.5 px wide:
    the middle row is wholly inside, at opacity true / drawn; the rows above and below are 3/4
    inside (12 of the 16 stratified samples), the next ones untouched. At spp 1 without the
    minimum, most pixels along the strand show nothing (the aliased dots of thin hair)."""
    w, h, true = 41, 31, 0.25 * PIXEL
    pts = np.linspace([-0.1, 0.0, 0.0], [0.1, 0.0, 0.0], 5)
    scene = RenderScene.from_strands(pts, [5], true)
    cam = camera(projection, w, h, depth)
    px = true / (PIXEL * (depth if projection == "perspective" else 1.0))   # true width in pixels
    rows = Renderer(w, h, spp=16, min_pixel_width=2.5, threads=1).render(scene, cam)[..., 3]
    opacity = px / 2.5
    mid = h // 2
    np.testing.assert_allclose(rows[mid], opacity, rtol=1e-5)
    np.testing.assert_allclose(rows[[mid - 1, mid + 1]], 0.75 * opacity, rtol=1e-5)
    assert rows[: mid - 1].max() == 0 and rows[mid + 2:].max() == 0
    # the same per column as the true width covers: px pixels of hair
    np.testing.assert_allclose(rows.sum(axis=0), px, rtol=1e-5)
    off = Renderer(w, h, spp=1, min_pixel_width=0, threads=1).render(scene, cam)[..., 3]
    on = Renderer(w, h, spp=1, min_pixel_width=1, threads=1).render(scene, cam)[..., 3]
    assert (off[mid] > 0).mean() < 0.5 and (on[mid] > 0).all()
    assert on[mid].sum() == pytest.approx(px * w, rel=1e-5)


@pytest.mark.parametrize("projection", ["perspective", "orthographic"])
def test_a_strand_wider_than_the_minimum_renders_exactly_as_without_it(projection):
    """Strands of 3 px (tapering to 1.5 px) over a sphere and a box, shaded, shadowed: with a minimum
    of 1 px nothing is widened and the image is bit for bit the one of true widths."""
    pts, counts, _ = field(6, H * PIXEL, z=0.0, axis=0, length=0.015)
    widths = np.tile(np.linspace(3.0, 1.5, 5) * PIXEL, 6)
    scene = RenderScene.from_strands(pts, counts, widths)
    scene.shapes.append(Shape(0, _translate(0.004, 0.002, -0.01), (0.006, 0.0, 0.0)))
    scene.shapes.append(Shape(BOX, _translate(0, 0, -0.05), (1.0, 1.0, 0.01)))
    cam = camera(projection)
    off = Renderer(W, H, spp=4, min_pixel_width=0, threads=1).render(scene, cam)
    on = Renderer(W, H, spp=4, min_pixel_width=1, threads=1).render(scene, cam)
    assert np.array_equal(on, off)
    # and a minimum above the narrow end changes the image
    wide = Renderer(W, H, spp=4, min_pixel_width=2.0, threads=1).render(scene, cam)
    assert not np.array_equal(wide, off)


@pytest.mark.parametrize("value, message", [
    (-1, "min_pixel_width -1: expected a width in pixels from 0 (off) to 64"),
    (float("nan"), "min_pixel_width nan: expected a width in pixels"),
    (100, "min_pixel_width 100: expected a width in pixels"),
    ("1", "min_pixel_width '1': expected a width in pixels"),
    (True, "min_pixel_width True: expected a width in pixels"),
])
def test_renderer_refuses_a_bad_minimum_pixel_width(value, message):
    with pytest.raises(ValueError) as e:
        Renderer(8, 8, min_pixel_width=value)
    assert message in str(e.value)


def render(*args):
    return cli.main(["render", *map(str, args), "-q"])


def test_min_pixel_width_on_the_command_line(tmp_path, capsys):
    """--min-pixel-width 0 draws true widths, the default 1 px draws a 0.2 px strand as a continuous
    line; a bad width is one line, exit 2, no image."""
    from dftl_warp.render.image import read_png

    path = tmp_path / "thin.usda"
    stage = new_stage(path)
    add_camera(stage, translate=(0, 0, 1.0), focal=50.0, aperture=(50 * PIXEL * W, 50 * PIXEL * H))
    add_curves(stage, "/hair", [np.linspace([-0.1, 0.0005, 0], [0.1, 0.0005, 0], 3)], widths=[0.2 * PIXEL])
    stage.Save()
    a, b = tmp_path / "default.png", tmp_path / "off.png"
    assert render(path, "--resolution", f"{W}x{H}", "--spp", 1, "-o", a) == 0
    assert render(path, "--resolution", f"{W}x{H}", "--spp", 1, "--min-pixel-width", 0, "-o", b) == 0
    seen_default = (read_png(a)[..., 3] > 0).sum(axis=0)
    seen_off = (read_png(b)[..., 3] > 0).sum(axis=0)
    assert (seen_default > 0).all() and (seen_off > 0).mean() < 0.5
    capsys.readouterr()
    out = tmp_path / "bad.png"
    assert render(path, "--min-pixel-width", "-2", "-o", out) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert lines == ["dftl-warp: error: --min-pixel-width -2.0: expected a width in pixels from 0 (off) to 64"]
    assert not out.exists()


def union_length(lo, hi, a, b):
    """Length of the union of the intervals [lo_i, hi_i] inside [a, b]."""
    lo, hi = np.clip(lo, a, b), np.clip(hi, a, b)
    order = np.argsort(lo)
    total, start, end = 0.0, lo[order[0]], hi[order[0]]
    for s, e in zip(lo[order[1:]], hi[order[1:]]):
        if s > end:
            total, start = total + end - start, s
        end = max(end, e)
    return total + end - start


def test_many_overlapping_thin_strands_cover_what_their_true_widths_cover():
    """250 horizontal strands of 0.25 px at random heights and depths (orthographic): up to ~50 drawn
    layers over a pixel at 8 px, composited front to back and then stochastically. The rendered
    coverage against the exact union of the true bands of the same strands: each realization within
    1 % at true widths; with the minimum width the layers are seen as independent (it cannot know
    where in its drawn width a hair lies), so single images scatter by a few percent both ways and
    their mean over 6 realizations is the true mean coverage."""
    n, w, frame = 250, 0.25 * PIXEL, H * PIXEL
    span = frame + 8 * PIXEL   # strands reach past the frame: no edge short of drawn neighbours
    exact, seen = [], {0.0: [], 3.0: [], 8.0: []}
    for seed in range(6):
        rng = np.random.default_rng(seed)
        ys, zs = rng.uniform(-span / 2, span / 2, n), rng.uniform(-0.02, 0.0, n)
        pts = np.concatenate([np.linspace([-0.03, y, z], [0.03, y, z], 3) for y, z in zip(ys, zs)])
        scene = RenderScene.from_strands(pts, np.full(n, 3), w)
        exact.append(union_length(ys - w / 2, ys + w / 2, -frame / 2, frame / 2) / frame)
        for min_width, values in seen.items():
            r = Renderer(W, H, spp=16, min_pixel_width=min_width, seed=seed, threads=1)
            values.append(float(r.render(scene, camera("orthographic"))[..., 3].mean()))
    np.testing.assert_allclose(seen[0.0], exact, rtol=0.01)
    for min_width in (3.0, 8.0):
        assert np.mean(seen[min_width]) == pytest.approx(np.mean(exact), rel=0.02), (min_width, seen, exact)
