"""``dftl-warp render``: ray-traced hair previews of a USD stage (one frame, a range, a turntable).

    dftl-warp render INPUT [--frame F | --start F --end F] [--camera PRIM] [--resolution WxH]
                     [--spp N] [--min-pixel-width W] [--device cpu|cuda:N] [--turntable N]
                     [--contact-sheet] -o OUT

OUT is a PNG for one frame; for several frames a pattern with a run of '#' (``hair.####.png``),
a video (``.mp4``, ``.gif``; needs the ``video`` extra), or, with ``--contact-sheet``, one PNG
holding every frame on a grid.
"""

from __future__ import annotations

import os
import re
import shutil
import sys
import tempfile
import time as _time
from pathlib import Path

from ..errors import UserError, WarningRoute, once

#: the most images one render makes (a --start/--end/--step range, or --turntable N)
MAX_IMAGES = 100_000


def add_parser(sub):
    from ..output.paths import path_argument
    from ..render.renderer import MAX_PIXEL_WIDTH, MAX_SIDE, MAX_SPP, MIN_PIXEL_WIDTH

    p = sub.add_parser(
        "render", help="render hair previews of a USD stage (PNG, image sequence, contact sheet, video)",
        description="Ray-trace the BasisCurves of a USD stage as tubes (with Sphere/Capsule/Cube/Mesh "
                    "gprims in a neutral material) through a UsdGeom.Camera or an automatic framing. "
                    "Writes RGBA PNGs with straight colour and alpha = coverage.")
    p.add_argument("input", metavar="INPUT", type=path_argument("the USD stage to render"),
                   help="USD stage (.usd, .usda, .usdc, .usdz)")
    g = p.add_mutually_exclusive_group()
    g.add_argument("--frame", type=float, help="time code to render (default: the stage's start time, or its default time)")
    g.add_argument("--start", type=float, help="first time code of a range (with --end)")
    p.add_argument("--end", type=float, help="last time code of a range, inclusive")
    p.add_argument("--step", type=float, default=None, help="time-code step of a --start/--end range (default 1)")
    p.add_argument("--camera", metavar="PRIM", type=path_argument("a UsdGeom.Camera prim path, or auto", file=False),
                   help="UsdGeom.Camera prim path, or 'auto' to frame the hair (default: the stage's first camera, "
                        "else auto)")
    p.add_argument("--resolution", default="960x540", metavar="WxH",
                   help=f"image size in pixels, each side 1 to {MAX_SIDE} (default 960x540)")
    p.add_argument("--spp", type=int, default=8, help=f"samples per pixel, 1 to {MAX_SPP} (default 8)")
    p.add_argument("--min-pixel-width", type=float, default=MIN_PIXEL_WIDTH, metavar="W",
                   help="draw a strand thinner than W pixels at its depth W pixels wide, its opacity scaled by "
                        "true / drawn width so as much hair is seen as its true width covers (real hair, "
                        f"40-100 um, is a fraction of a pixel in a preview); 0 draws true widths; at most "
                        f"{MAX_PIXEL_WIDTH:g} (default {MIN_PIXEL_WIDTH:g})")
    p.add_argument("--device", default=None,
                   help="Warp device: cpu or cuda:N (default cuda:0 when there is a CUDA device, else cpu)")
    p.add_argument("--shading", default="marschner", choices=("marschner", "kajiya-kay"), help="hair shading model")
    p.add_argument("--conform", default="expandAperture",
                   choices=("expandAperture", "cropAperture", "adjustApertureWidth", "adjustApertureHeight"),
                   help="how the camera aperture meets a different image aspect (UsdRender policy; default expandAperture)")
    p.add_argument("--turntable", type=int, metavar="N",
                   help=f"N frames orbiting the hair once around the up axis (at most {MAX_IMAGES})")
    p.add_argument("--contact-sheet", action="store_true", help="write all frames as one grid image to OUT")
    p.add_argument("--fps", type=float, default=None,
                   help="frames per second of a video OUT (.mp4, .gif, ...; default 24)")
    p.add_argument("-o", "--output", required=True, metavar="OUT",
                   type=path_argument("the image to write, such as out/hair.png"),
                   help="PNG, pattern like frames/hair.####.png, .mp4 or .gif")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress output")
    p.set_defaults(run=run)


def parse_resolution(text: str):
    from ..render.renderer import MAX_SIDE

    try:
        w, h = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise UserError(f"--resolution {text!r}: expected WIDTHxHEIGHT, e.g. 1920x1080") from None
    if not (1 <= w <= MAX_SIDE and 1 <= h <= MAX_SIDE):
        raise UserError(f"--resolution {text!r}: width and height must be between 1 and {MAX_SIDE}")
    return w, h


def time_code(t: float) -> str:
    """A time code as written, every digit that tells it apart (1000003, 1e+20, 0.5; ``:g`` shows
    1000003 as 1e+06)."""
    text = repr(float(t))
    return text[:-2] if text.endswith(".0") else text


def _check_numbers(args) -> None:
    """Time codes finite (``--frame nan`` rendered the default time without a word), and --spp
    and --turntable within the renderer's limits, before the stage is read."""
    import math

    from ..render.renderer import MAX_SPP, pixel_width, whole_number

    from ..options import MAX_FRAME

    for flag in ("frame", "start", "end", "step"):
        value = getattr(args, flag)
        if value is not None and not math.isfinite(value):
            raise UserError(f"--{flag} {value:g}: expected a finite time code")
        if value is not None and flag != "step" and abs(value) > MAX_FRAME:   # as simulate's --start/--end
            raise UserError(f"--{flag} {time_code(value)}: past +-{float(MAX_FRAME):g}, where a time code (a double) "
                            "cannot tell frames apart")
    if args.step is not None and args.step <= 0:
        raise UserError(f"--step {args.step:g}: must be positive")
    whole_number("--spp", args.spp, 1, MAX_SPP)
    pixel_width("--min-pixel-width", args.min_pixel_width)
    if args.turntable is not None:
        whole_number("--turntable", args.turntable, 1, MAX_IMAGES)


def _frames(args, stage):
    """Time codes to render (a list; None = the stage's default time)."""
    from ..render import usd_scene

    if args.end is not None and args.start is None:
        raise UserError("--end needs --start")
    if args.start is not None:
        if args.end is None:
            raise UserError("--start needs --end")
        if args.end < args.start:
            raise UserError(f"--end {args.end:g} is before --start {args.start:g}")
        step = 1.0 if args.step is None else args.step
        span = (args.end - args.start) / step   # frames after the first (inf for a tiny --step)
        if span + 1 > MAX_IMAGES:
            raise UserError(f"--start {args.start:g} --end {args.end:g} --step {step:g}: {span + 1:.6g} frames; "
                            f"one render makes at most {MAX_IMAGES}")
        n = int(span + 1e-9) + 1
        times = [args.start + k * step for k in range(n)]
        if len(set(times)) < n:   # a step below the spacing of doubles there: frames would repeat
            raise UserError(f"--start {time_code(args.start)} --end {time_code(args.end)} --step {time_code(step)}: "
                            "the step is below what a time code (a double) can tell apart there: frames would repeat")
        return times
    if args.frame is not None:
        return [args.frame]
    from ..options import MAX_FRAME

    r = usd_scene.time_range(stage)
    if r and abs(r[0]) > MAX_FRAME:   # the frame rendered by default: refused as simulate refuses the range
        raise UserError(f"{args.input}: the stage's startTimeCode {time_code(r[0])} (the time rendered by default) "
                        f"lies past +-{float(MAX_FRAME):g}, where a time code (a double) cannot tell frames apart; "
                        f"give --frame or --start and --end")
    return [r[0] if r else None]


def _check_output(args, n_images: int):
    from ..render.image import VIDEO_SUFFIXES, has_pattern

    out = args.output
    suffix = Path(out).suffix.lower()
    if len(re.findall(r"#+", out)) > 1:   # only the first run was numbered: hair.0001.v##.png
        raise UserError(f"-o {out}: more than one run of '#': a pattern numbers frames with one (hair.####.png)")
    if args.contact_sheet or n_images == 1:
        if suffix != ".png" or has_pattern(out) and args.contact_sheet:
            raise UserError(f"-o {out}: expected a .png file name")
        return "png"
    if suffix in VIDEO_SUFFIXES:
        return "video"
    if suffix != ".png":
        raise UserError(f"-o {out}: expected .png, a pattern like frames/hair.####.png, or .mp4/.gif")
    if not has_pattern(out):
        raise UserError(f"-o {out}: {n_images} frames need a pattern with '#' (e.g. hair.####.png), "
                        "a video (.mp4, .gif) or --contact-sheet")
    return "pattern"


def _check_frame_numbers(args, times, kind: str) -> None:
    """A '#' pattern is numbered by frame, so every frame must be whole (``hair.0001.5.png`` is
    no name an image-sequence tool reads)."""
    from ..render.image import has_pattern, is_whole

    if kind not in ("pattern", "png") or not has_pattern(args.output) or args.turntable:
        return
    for t in times:
        if t is not None and not is_whole(t):
            step = f" (--step {1.0 if args.step is None else args.step:g})" if args.start is not None else ""
            raise UserError(f"-o {args.output}: frame {t:g}{step} is not a whole number: a '#' pattern is "
                            "numbered by frame; render whole frames, or write a video (.mp4, .gif) "
                            "or --contact-sheet")


def _check_fps(args) -> float:
    """The video frame rate (default 24); --fps must be a positive, finite number."""
    import math

    if args.fps is None:
        return 24.0
    if not (math.isfinite(args.fps) and args.fps > 0):
        raise UserError(f"--fps {args.fps:g}: must be a positive, finite number of frames per second")
    return args.fps


def _blind_warning(cam_path: str, labels: list, n_images: int, args) -> str:
    """The line for a camera that saw no strand in the images ``labels`` (time codes, None for the
    default time, or turntable indices)."""
    who = "the automatic camera (--camera auto)" if cam_path == "auto" else f"camera {cam_path}"
    if args.turntable:   # views numbered from 0, as a pattern numbers them
        shown = ", ".join(str(k) for k in labels[:5])
        where = f"in turntable view{'s' if len(labels) > 1 else ''} {shown}"
    elif labels == [None]:
        where = "at the stage's default time"
    else:
        shown = ", ".join(f"{t:g}" for t in labels[:5])
        where = f"at frame{'s' if len(labels) > 1 else ''} {shown}"
    if len(labels) > 5:
        where += ", ..."
    if n_images > 1:
        where += f" ({len(labels)} of {n_images} images)"
    if args.min_pixel_width > 0:   # thin strands are widened: only a strand shorter than the samples' spacing hides
        wide = f"{args.min_pixel_width:g} pixel{'' if args.min_pixel_width == 1 else 's'}"
        size = (f"smaller in the image than the spacing of --spp {args.spp} samples (--min-pixel-width "
                f"{args.min_pixel_width:g} widens strands to {wide}, it does not lengthen them)")
    else:
        size = (f"too thin for --spp {args.spp} (--min-pixel-width 0 draws true widths; a width of 1 draws them at "
                f"least a pixel wide)")
    return (f"{who} sees no strand {where}: no strand sample lands in the image (it looks away from the hair, or the "
            f"hair is outside its clipping range, hidden behind geometry or {size})")


def run(args) -> int:
    # Python warnings (numpy's RuntimeWarnings on extreme sizes, ...): one line naming the input, once each
    with WarningRoute(where=args.input) as route:
        return _render(args, route)


def _render(args, route) -> int:
    from ..core.devices import device_line, resolve_device
    from ..output.paths import check_writable
    from ..render import image, usd_scene
    from ..render.renderer import Renderer, orbit_cameras, to_rgba8

    width, height = parse_resolution(args.resolution)
    fps = _check_fps(args)
    _check_numbers(args)
    if args.turntable and args.start is not None:
        raise UserError("--turntable orbits one frame: give --frame, not --start/--end")

    def warn(text):
        print(f"dftl-warp: warning: {text}", file=sys.stderr)

    stage_warnings = []
    route.keep_in(stage_warnings)   # said with the stage's, once the first frame is read
    stage = usd_scene.open_stage(args.input, stage_warnings)
    source = args.input
    times = _frames(args, stage)
    n_images = args.turntable or len(times)
    kind = _check_output(args, n_images)
    _check_frame_numbers(args, times, kind)
    # everything that can fail is checked before the first frame is rendered
    usd_scene.check_samples(stage, times, source)
    stage_warnings.extend(usd_scene.render_notes(stage, source))
    first_number = 0 if args.turntable or times[0] is None else times[0]   # a turntable's views count from 0
    check_writable(image.frame_path(args.output, first_number) if kind == "pattern" else args.output)
    if kind == "video":
        image.check_video(args.output)
    args.device = resolve_device(args.device)
    renderer = Renderer(width, height, spp=args.spp, device=args.device, shading=args.shading, conform=args.conform,
                        min_pixel_width=args.min_pixel_width)
    if not args.quiet:
        print(device_line(args.device), file=sys.stderr)

    cam_path = args.camera
    if cam_path is None:
        found = usd_scene.cameras(stage)
        cam_path = found[0] if found else "auto"

    def read(t):
        scene = usd_scene.read_render_scene(stage, t, source)
        if usd_scene.is_empty(scene):
            at = "" if t is None else f" at frame {t:g}"
            raise UserError(f"{source}: nothing to render{at}: no visible BasisCurves with a segment (2 or more "
                            "vertices), Sphere, Capsule, Cube or Mesh prim (an output whose input moved?)")
        return scene

    def camera_at(t, scene):
        if cam_path == "auto":
            return renderer.default_camera(scene)
        return usd_scene.read_camera(stage, cam_path, t, source)

    jobs = []  # (label, scene, camera)
    if args.turntable:
        scene = read(times[0])
        cams = orbit_cameras(camera_at(times[0], scene), scene, args.turntable)
        jobs = [(k, scene, c) for k, c in enumerate(cams)]
    else:
        first = read(times[0])  # the first frame's data and camera are checked before any warning
        jobs = [(times[0], first, camera_at(times[0], first))] + [(t, None, None) for t in times[1:]]
    # warnings once nothing before the first image can fail; -q silences progress, not warnings
    if args.fps is not None and kind != "video":
        warn(f"--fps applies only to a video output (.mp4, .gif, .mov, .webm): ignored for -o {args.output}")
    if args.step is not None and args.start is None:
        warn(f"--step {args.step:g} applies only to a --start/--end range: ignored")
    for w in stage_warnings:
        warn(w)
    route.say = once(warn, stage_warnings)   # from now on as they come

    frames = []
    say = (lambda *a: None) if args.quiet else (lambda *a: print(*a, file=sys.stderr))
    t_all = _time.perf_counter()
    # a sequence's frames wait in a hidden folder beside it and move into place once every frame
    # has rendered: a frame that fails leaves no part of the sequence behind
    staged = []  # (temporary path, final path)
    blind = []  # the labels of images in which the camera saw no strand
    pending = None
    if kind == "pattern":
        first = Path(image.frame_path(args.output, jobs[0][0] if jobs[0][0] is not None else 0)).resolve().parent
        try:
            first.mkdir(parents=True, exist_ok=True)
            pending = tempfile.mkdtemp(prefix=".dftl-render-", dir=first)
        except OSError as exc:
            raise UserError(f"{first}: cannot write: {exc.strerror or exc}") from None
    try:
        for k, (label, scene, cam) in enumerate(jobs):
            if scene is None:
                scene = read(label)
                cam = camera_at(label, scene)
            t0 = _time.perf_counter()
            rgba = to_rgba8(renderer.render(scene, cam))
            dt = _time.perf_counter() - t0
            if not renderer.hair_visible and scene.segment_count:
                blind.append(label)
            number = label if label is not None else 0
            if kind == "pattern":
                path = image.frame_path(args.output, number)
                staged.append((os.path.join(pending, f"{k:08d}.png"), path))
                image.write_png(staged[-1][0], rgba)
                say(f"{path}  {dt:.2f} s")
            elif kind == "png" and n_images == 1:
                path = image.frame_path(args.output, number)
                image.write_png(path, rgba)
                say(f"{path}  {dt:.2f} s")
            else:
                frames.append(rgba)
                say(f"frame {k + 1}/{n_images}  {dt:.2f} s")
        for tmp, path in staged:
            try:
                Path(path).parent.mkdir(parents=True, exist_ok=True)
                os.replace(tmp, path)
            except OSError as exc:
                raise UserError(f"{path}: cannot write: {exc.strerror or exc}") from None
    finally:
        if pending is not None:
            shutil.rmtree(pending, ignore_errors=True)
    if kind == "video":
        image.write_video(args.output, frames, fps=fps)
        say(f"{args.output}  {len(frames)} frames")
    elif frames:
        image.write_png(args.output, image.contact_sheet(frames))
        say(f"{args.output}  contact sheet of {len(frames)} frames")
    if blind:   # once every image is written: a render that fails later says only why
        warn(_blind_warning(cam_path, blind, n_images, args))
    if n_images > 1:
        say(f"{n_images} frames in {_time.perf_counter() - t_all:.1f} s")
    return 0
