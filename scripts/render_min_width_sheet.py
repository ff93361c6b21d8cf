#!/usr/bin/env python3
"""Before/after sheet of the renderer's minimum pixel width on a real groom: one frame rendered by
``dftl-warp render`` with ``--min-pixel-width 0`` (true widths) and with the default (1 px), side by
side over a flat background, and below them the same window of both, zoomed (nearest neighbour,
so the pixels show). The window is where the two images differ most (``--crop X,Y`` picks one).

    python scripts/render_min_width_sheet.py GROOM.usda --out docs/img/min_width_sintel.png
        [--frame F] [--camera PRIM|auto] [--resolution 640x360] [--spp 8] [--device cpu]
        [--widths 0 1] [--zoom 4] [--crop X,Y] [--background R,G,B] [--title TEXT] [--credit TEXT]

GROOM is any stage ``dftl-warp render`` reads, e.g. a groom brought in by ``dftl-warp import``
(docs/grooms.md: where the public grooms come from and their licences). Prints each render's time
(``dftl-warp render``'s own figure: the renderer alone, after a tiny warm-up render that loads the
kernels), how much of the background the hair covers in each (the sum of alpha over the pixels not
opaque in both: the minimum width should keep it) and in how many pixels, the strands' true width in
pixels, and the crop window. Bad input: ``dftl-warp render``'s one line, its exit status, no sheet.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import re
import sys
import tempfile
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw, ImageFont

from dftl_warp import cli
from dftl_warp.durable import write_file
from dftl_warp.render.image import over_background

LABEL_H = 24
GAP = 6


def render(groom: str, out: Path, width: str, args, quiet: bool = False, resolution: str | None = None):
    """Run ``dftl-warp render`` once; returns (exit status, its time for the frame in s or None).
    ``quiet``: its stderr is shown only if it fails."""
    argv = ["render", groom, "--resolution", resolution or args.resolution, "--spp", str(args.spp),
            "--device", args.device, "--min-pixel-width", width, "-o", str(out)]
    if args.frame is not None:
        argv += ["--frame", args.frame]
    if args.camera is not None:
        argv += ["--camera", args.camera]
    if quiet:
        argv.append("-q")
    said = io.StringIO()
    with contextlib.redirect_stderr(said):
        rc = cli.main(argv)
    if rc or not quiet:  # a warm-up's warnings (its 16x9 image may see no strand) are not the sheet's
        sys.stderr.write(said.getvalue())
    found = re.search(rf"^{re.escape(str(out))}\s+([0-9.]+) s$", said.getvalue(), re.MULTILINE)
    return rc, (float(found.group(1)) if found else None)


def busiest_window(a: np.ndarray, b: np.ndarray, w: int, h: int) -> tuple[int, int]:
    """Top-left corner of the w x h window where ``a`` and ``b`` (H x W x 3) differ most."""
    diff = np.abs(a.astype(np.int64) - b.astype(np.int64)).sum(axis=2)
    s = np.zeros((diff.shape[0] + 1, diff.shape[1] + 1), dtype=np.int64)
    s[1:, 1:] = diff.cumsum(0).cumsum(1)
    sums = s[h:, w:] - s[:-h, w:] - s[h:, :-w] + s[:-h, :-w]
    y, x = np.unravel_index(int(np.argmax(sums)), sums.shape)
    return int(x), int(y)


def pixel_widths(groom: str, args, width: int, height: int):
    """Every strand vertex's true width in pixels at its depth, through the camera the render used,
    and the time code rendered."""
    from pxr import Usd

    from dftl_warp.render import usd_scene
    from dftl_warp.render.camera import auto_frame

    stage = usd_scene.open_stage(groom)
    t = usd_scene.default_time(stage) if args.frame is None else Usd.TimeCode(float(args.frame))
    scene = usd_scene.read_render_scene(stage, t, groom)
    path = args.camera or (usd_scene.cameras(stage) or ["auto"])[0]
    if path == "auto":  # Renderer.default_camera, without building a renderer
        cam = auto_frame(scene.hair_bounds() or scene.bounds(), width, height, scene.up_axis)
    else:
        cam = usd_scene.read_camera(stage, path, t, groom)
    _, depth = cam.world_to_pixel(scene.points, width, height)
    left, right, _, _ = cam.screen_window(width, height)
    per_pixel = (right - left) / width * (1.0 if cam.projection == "orthographic" else depth)
    return 2.0 * scene.radii / per_pixel, t


def font(size: int):
    try:
        return ImageFont.load_default(size=size)
    except TypeError:  # Pillow < 10.1: one bitmap size
        return ImageFont.load_default()


def sheet(panels, crops, box, zoom: int, title: str, credit: str) -> Image.Image:
    """Row 1: the full frames (the crop window outlined); row 2: the crops zoomed; labels above."""
    h, w = panels[0][1].shape[:2]
    cols = len(panels)
    width = cols * w + (cols - 1) * GAP
    head = LABEL_H + 4
    foot = LABEL_H if credit else 0
    im = Image.new("RGB", (width, head + 2 * (LABEL_H + h) + GAP + foot), (255, 255, 255))
    draw = ImageDraw.Draw(im)
    big, small = font(16), font(13)
    draw.text((4, 4), title, fill=(0, 0, 0), font=big)
    x0, y0, cw, ch = box
    for c, ((label, rgb), crop) in enumerate(zip(panels, crops)):
        left = c * (w + GAP)
        top = head
        draw.text((left + 4, top + 4), label, fill=(0, 0, 0), font=small)
        im.paste(Image.fromarray(rgb), (left, top + LABEL_H))
        draw.rectangle([left + x0 - 1, top + LABEL_H + y0 - 1, left + x0 + cw, top + LABEL_H + y0 + ch],
                       outline=(220, 30, 30), width=1)
        top += LABEL_H + h + GAP
        draw.text((left + 4, top + 4), f"{label}: the red window x{zoom}", fill=(0, 0, 0), font=small)
        zoomed = Image.fromarray(crop).resize((cw * zoom, ch * zoom), Image.NEAREST)
        im.paste(zoomed, (left, top + LABEL_H))
    if credit:
        draw.text((4, im.height - foot + 5), credit, fill=(60, 60, 60), font=small)
    return im


def parse_crop(text: str) -> tuple[int, int]:
    try:
        x, y = (int(v) for v in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"--crop {text!r}: expected X,Y in pixels, e.g. 300,80") from None
    return x, y


def parse_rgb(text: str) -> tuple[int, int, int]:
    try:
        rgb = tuple(int(v) for v in text.split(","))
    except ValueError:
        rgb = ()
    if len(rgb) != 3 or not all(0 <= v <= 255 for v in rgb):
        raise argparse.ArgumentTypeError(f"--background {text!r}: expected R,G,B from 0 to 255, e.g. 236,236,236")
    return rgb


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("groom", help="USD stage to render (not copied anywhere)")
    ap.add_argument("--out", required=True, help="the sheet (.png)")
    ap.add_argument("--frame", default=None)
    ap.add_argument("--camera", default=None)
    ap.add_argument("--resolution", default="640x360")
    ap.add_argument("--spp", type=int, default=8)
    ap.add_argument("--device", default="cpu")
    ap.add_argument("--widths", nargs=2, default=["0", "1"], metavar=("OFF", "ON"),
                    help="the two --min-pixel-width values (default 0 and 1, the render default)")
    ap.add_argument("--zoom", type=int, default=4, choices=range(1, 17), metavar="1..16")
    ap.add_argument("--crop", type=parse_crop, default=None, help="top-left X,Y of the zoomed window")
    ap.add_argument("--background", type=parse_rgb, default=(236, 236, 236), help="R,G,B under the transparent pixels")
    ap.add_argument("--title", default="", help="text before the sheet's own title (file, frame, size, width)")
    ap.add_argument("--credit", default="", help="a line under the sheet (the groom's source and licence)")
    args = ap.parse_args(argv)
    size = re.fullmatch(r"(\d+)x(\d+)", args.resolution)
    if args.crop is not None and size:  # else dftl-warp render names the bad --resolution
        w, h = int(size.group(1)), int(size.group(2))
        cw, ch = w // args.zoom, h // args.zoom
        if not (0 <= args.crop[0] <= w - cw and 0 <= args.crop[1] <= h - ch):
            print(f"render_min_width_sheet: error: --crop {args.crop[0]},{args.crop[1]}: a {cw}x{ch} window "
                  f"must fit in {w}x{h}", file=sys.stderr)
            return 2

    with tempfile.TemporaryDirectory(prefix="min_width_sheet_") as tmp:
        for width in args.widths:  # loads (and, on a cold cache, compiles) the kernels of both paths
            rc, _ = render(args.groom, Path(tmp) / f"warm{width}.png", width, args, quiet=True, resolution="16x9")
            if rc:
                return rc
        panels, alphas = [], []
        for width in args.widths:
            png = Path(tmp) / f"min_width_{width}.png"
            rc, seconds = render(args.groom, png, width, args)
            if rc:
                return rc
            rgba = np.asarray(Image.open(png).convert("RGBA"))
            alphas.append(rgba[..., 3] / 255.0)
            rgb = over_background(rgba, args.background)
            default = " (the default)" if float(width) == 1.0 else (" (true widths)" if float(width) == 0 else "")
            label = f"--min-pixel-width {width}{default}"
            print(f"{label}: {seconds if seconds is not None else float('nan'):.2f} s", flush=True)
            panels.append((label, rgb))

    free = (alphas[0] < 1.0) | (alphas[1] < 1.0)  # not covered by geometry (or opaque hair) in both
    for (label, _), alpha in zip(panels, alphas):
        print(f"{label}: hair over the background covers {alpha[free].sum():.0f} pixels' worth, "
              f"{np.count_nonzero(alpha[free])} pixels show some", flush=True)
    h, w = panels[0][1].shape[:2]
    px, t = pixel_widths(args.groom, args, w, h)
    print(f"true strand width: {np.median(px):.3f} px (median of the vertices; 5-95 %: "
          f"{np.percentile(px, 5):.3f}-{np.percentile(px, 95):.3f} px)", flush=True)
    frame = "default time" if t.IsDefault() else f"frame {t.GetValue():g}"
    title = (f"{args.title + ': ' if args.title else ''}{Path(args.groom).name}, {frame}, {w}x{h}, {args.spp} spp; "
             f"strands {np.median(px):.2g} px wide at their true width")
    cw, ch = w // args.zoom, h // args.zoom
    x0, y0 = args.crop if args.crop is not None else busiest_window(panels[0][1], panels[1][1], cw, ch)
    print(f"crop window: x {x0}..{x0 + cw}, y {y0}..{y0 + ch} (x{args.zoom})", flush=True)
    crops = [rgb[y0:y0 + ch, x0:x0 + cw] for _, rgb in panels]
    im = sheet(panels, crops, (x0, y0, cw, ch), args.zoom, title, args.credit)
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    write_file(out, lambda tmp: im.save(tmp, format="PNG", optimize=True))
    print(f"{out}: {im.width}x{im.height}, {out.stat().st_size / 1024:.0f} KiB", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
