"""``dftl-warp render``: outputs (PNG, patterns, turntables, contact sheets, GIF) and bad input."""

import subprocess
import sys

import numpy as np
import pytest

from dftl_warp import cli
from dftl_warp.render.image import read_png
from render_util import add_camera, add_curves, alpha_centroid, new_stage


def write_stage(path, frames=(1, 2, 3)):
    stage = new_stage(path)
    stage.SetStartTimeCode(frames[0])
    stage.SetEndTimeCode(frames[-1])
    add_camera(stage, translate=(0, 0.5, 3))
    base = [np.array([[x, 0, 0], [x, 0.5, 0.1], [x + 0.1, 1.0, 0]]) for x in np.linspace(-0.5, 0.5, 10)]
    for f in frames:
        add_curves(stage, "/hair", [s + [0.1 * f, 0, 0] for s in base], widths=[0.03], time=f)
    stage.Save()
    return path


@pytest.fixture
def stage_file(tmp_path):
    return write_stage(tmp_path / "groom.usda")


def render(*args):
    return cli.main(["render", *map(str, args), "-q"])


def test_one_frame_png_is_rgba_with_straight_alpha(stage_file, tmp_path):
    out = tmp_path / "one.png"
    # the strands are 0.9 px wide: at their true width (no minimum) some pixel's 4 samples all hit one
    assert render(stage_file, "--frame", 2, "--resolution", "64x48", "--spp", 4, "--min-pixel-width", 0,
                  "-o", out) == 0
    img = read_png(out)
    assert img.shape == (48, 64, 4)
    a = img[..., 3]
    assert 0 < (a > 0).mean() < 0.5 and a.max() == 255
    # straight colour: partly covered pixels are as bright as covered ones, empty ones are 0
    assert (img[a == 0][:, :3] == 0).all()
    edge = (a > 0) & (a < 128)
    assert img[edge][:, :3].astype(float).mean() > 0.5 * img[a == 255][:, :3].astype(float).mean()


def test_range_output_pattern(stage_file, tmp_path):
    pattern = tmp_path / "frames" / "hair.####.png"
    assert render(stage_file, "--start", 1, "--end", 3, "--resolution", "48x32", "--spp", 2, "-o", pattern) == 0
    names = sorted(p.name for p in (tmp_path / "frames").iterdir())
    assert names == ["hair.0001.png", "hair.0002.png", "hair.0003.png"]
    xs = [alpha_centroid(read_png(tmp_path / "frames" / n)[..., 3].astype(float))[0] for n in names]
    assert xs[0] < xs[1] < xs[2]  # the groom moves +x from frame to frame
    # a two-digit pattern and a step
    assert render(stage_file, "--start", 1, "--end", 3, "--step", 2, "--resolution", "16x16", "--spp", 1,
                  "-o", tmp_path / "b" / "f_##.png") == 0
    assert sorted(p.name for p in (tmp_path / "b").iterdir()) == ["f_01.png", "f_03.png"]


def test_turntable_contact_sheet_and_gif(stage_file, tmp_path):
    sheet = tmp_path / "sheet.png"
    assert render(stage_file, "--turntable", 4, "--contact-sheet", "--camera", "auto", "--resolution", "40x30",
                  "--spp", 1, "-o", sheet) == 0
    img = read_png(sheet)
    assert img.shape == (2 * 30 + 4, 2 * 40 + 4, 4)
    tiles = [img[r * 34:r * 34 + 30, c * 44:c * 44 + 40, 3] for r in (0, 1) for c in (0, 1)]
    assert all(t.sum() > 0 for t in tiles)
    assert not np.array_equal(tiles[0], tiles[1])  # the view turned
    gif = tmp_path / "range.gif"
    assert render(stage_file, "--start", 1, "--end", 3, "--resolution", "32x24", "--spp", 1, "-o", gif) == 0
    import imageio.v3 as iio

    assert iio.imread(gif, index=None).shape[:3] == (3, 24, 32)


def bad_cases(tmp_path, stage_file):
    junk = tmp_path / "junk.usda"
    junk.write_text("this is not usd\n")
    bad_counts = tmp_path / "bad.usda"
    stage = new_stage(bad_counts)
    c = add_curves(stage, "/groom/hair", [np.zeros((3, 3)), np.ones((2, 3))], widths=[0.1])
    from pxr import Vt

    c.GetCurveVertexCountsAttr().Set(Vt.IntArray([3, 4]))
    stage.Save()
    return [
        ([tmp_path / "missing.usda"], "missing.usda: no such file"),
        ([junk], "junk.usda: cannot open as a USD stage"),
        ([bad_counts], "bad.usda: /groom/hair: points has 5 entries but curveVertexCounts sums to 7"),
        ([stage_file, "--camera", "/nope"], "groom.usda: /nope: no UsdGeom.Camera prim"),
        ([stage_file, "--resolution", "12by3"], "--resolution '12by3'"),
        ([stage_file, "--start", 1, "--end", 3], "3 frames need a pattern"),
        ([stage_file, "--start", 3, "--end", 1, "-o", tmp_path / "x.####.png"], "--end 1 is before --start 3"),
        ([stage_file, "--device", "cuda:7"], "device 'cuda:7' is not available"),
        ([stage_file, "--spp", 0], "--spp 0: must be at least 1"),
    ]


def test_bad_input_one_line_exit_2_no_output(stage_file, tmp_path, capsys):
    for args, message in bad_cases(tmp_path, stage_file):
        out = tmp_path / "out.png"
        if "-o" not in args:
            args = [*args, "-o", out]
        assert render(*args) == 2, args
        err = capsys.readouterr().err
        lines = err.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith("dftl-warp: error: ") and message in lines[0], err
        assert not out.exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad.usda", "groom.usda", "junk.usda"]


def test_failed_write_leaves_no_file(stage_file, tmp_path, monkeypatch):
    from PIL import Image

    def broken_save(self, fp, *a, **k):
        with open(fp, "wb") as f:
            f.write(b"\x89PNG half")
        raise OSError("disk full")

    monkeypatch.setattr(Image.Image, "save", broken_save)
    assert render(stage_file, "--resolution", "8x8", "--spp", 1, "-o", tmp_path / "x.png") == 2  # one line, no traceback
    assert sorted(p.name for p in tmp_path.iterdir()) == ["groom.usda"]


def test_command_line_error_has_no_traceback(tmp_path):
    r = subprocess.run([sys.executable, "-m", "dftl_warp", "render", str(tmp_path / "nothing.usda"), "-o",
                        str(tmp_path / "x.png")], capture_output=True, text=True)
    assert r.returncode == 2
    assert r.stderr.strip().splitlines() == [f"dftl-warp: error: {tmp_path / 'nothing.usda'}: no such file"]
    assert not (tmp_path / "x.png").exists()


def test_output_gets_ordinary_file_permissions(stage_file, tmp_path):
    import os
    import stat

    out = tmp_path / "p.png"
    assert render(stage_file, "--resolution", "8x8", "--spp", 1, "-o", out) == 0
    umask = os.umask(0)
    os.umask(umask)
    assert stat.S_IMODE(out.stat().st_mode) == 0o666 & ~umask
