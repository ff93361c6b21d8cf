"""Render time per frame: a numpy groom of 100k strands at 1920x1080, 4 samples per pixel.

    python scripts/bench_render.py --device cpu --out DIR [--strands N] [--resolution WxH] [--spp N]

``run(device, out_dir, ...)`` returns markdown table rows (the header is ``HEADER``) and writes
them to ``out_dir/bench_render.md`` together with the last frame as ``bench_render.png``.
Timings: the first frame (scene upload + BVH build + render; kernels are compiled beforehand
by a tiny warm-up render and not counted), then ``frames`` further frames in which every
strand moved (device upload + segment boxes + ``bvh.refit()`` + render + copy back): their
mean is the time per frame.
"""

from __future__ import annotations

import argparse
import os
import platform
import sys
import time
from pathlib import Path

import numpy as np


HEADER = ("| device | strands | segments | resolution | spp | first frame (build) s | time per frame (refit) s "
          "| camera Mrays/s | CPU threads | load avg (1 min) |\n"
          "|---|---|---|---|---|---|---|---|---|---|")


def groom_scene(strands: int, vertices: int, seed: int = 0):
    from dftl_warp.render import RenderScene, Shape
    from dftl_warp.render.groom import sphere_groom
    from dftl_warp.render.scene import SPHERE

    pts, counts = sphere_groom(strands, vertices, radius=0.1, length=0.15, seed=seed)
    u = np.tile(np.linspace(0.0, 1.0, vertices), strands)
    scene = RenderScene.from_strands(pts, counts, widths=1.0e-4 * (1.0 - 0.5 * u))  # 100 um, tapered
    scene.shapes.append(Shape(SPHERE, np.eye(4), (0.1, 0.0, 0.0), "/head"))
    return scene


def cpu_name() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "cpu"


def run(device: str, out_dir, strands: int = 100_000, vertices: int = 16, resolution=(1920, 1080),
        spp: int = 4, frames: int = 2, threads: int | None = None, min_pixel_width: float | None = None) -> str:
    from dftl_warp.core.devices import init_warp

    init_warp()
    import warp as wp

    from dftl_warp.render import Renderer, to_rgba8
    from dftl_warp.render.image import write_png

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    width, height = resolution
    scene = groom_scene(strands, vertices)
    # compile the kernels on a tiny frame first
    Renderer(8, 8, spp=1, device=device).render(groom_scene(10, vertices))
    extra = {} if min_pixel_width is None else {"min_pixel_width": min_pixel_width}
    renderer = Renderer(width, height, spp=spp, device=device, threads=threads, **extra)
    camera = renderer.default_camera(scene)
    wp.synchronize_device(device)
    load = os.getloadavg()[0]
    t0 = time.perf_counter()
    img = renderer.render(scene, camera)
    first = time.perf_counter() - t0
    times = []
    rng = np.random.default_rng(1)
    for _ in range(frames):
        # every strand sways a little: same topology, new positions -> refit
        sway = rng.normal(scale=0.002, size=(strands, 1, 3)) * np.linspace(0, 1, vertices)[None, :, None]
        scene.points = scene.points + sway.reshape(-1, 3)
        t0 = time.perf_counter()
        img = renderer.render(scene, camera)
        times.append(time.perf_counter() - t0)
    assert renderer.bvh_builds == 1 and renderer.bvh_refits == frames
    per_frame = float(np.mean(times))
    write_png(out / "bench_render.png", to_rgba8(img))
    dev = wp.get_device(device)
    name = dev.name if dev.is_cuda else cpu_name()
    mrays = width * height * spp / per_frame / 1e6
    row = (f"| {device} ({name}) | {strands} | {scene.segment_count} | {width}x{height} | {spp} | {first:.2f} "
           f"| {per_frame:.2f} | {mrays:.2f} | {'-' if dev.is_cuda else renderer.threads} | {load:.2f} |")
    (out / "bench_render.md").write_text(HEADER + "\n" + row + "\n")
    return row


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--device", default="cpu")
    ap.add_argument("--out", default="out/bench_render")
    ap.add_argument("--strands", type=int, default=100_000)
    ap.add_argument("--vertices", type=int, default=16)
    ap.add_argument("--resolution", default="1920x1080")
    ap.add_argument("--spp", type=int, default=4)
    ap.add_argument("--frames", type=int, default=2, help="timed frames after the first")
    ap.add_argument("--threads", type=int, help="CPU threads (default: all cores)")
    ap.add_argument("--min-pixel-width", type=float, default=None,
                    help="the renderer's minimum pixel width (default: the Renderer's, 1 px; 0: true widths)")
    args = ap.parse_args(argv)
    w, h = (int(v) for v in args.resolution.split("x"))
    row = run(args.device, args.out, args.strands, args.vertices, (w, h), args.spp, args.frames, args.threads,
              args.min_pixel_width)
    print(HEADER)
    print(row)
    return 0


if __name__ == "__main__":
    sys.exit(main())
