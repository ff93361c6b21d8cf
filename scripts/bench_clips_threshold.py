#!/usr/bin/env python3
"""Above which size value clips write faster than one layer: the measurement behind automatic
clips (``output/clips.py: auto_clips``, ``AUTO_MIN_POINTS``, ``AUTO_MIN_FRAMES``; docs/caches.md,
"Chosen automatically").

For each points-per-frame count and frame count, random frames (points and velocities, each frame
different; the groom of ``make_scenes.make_default`` with 16 vertices per strand) are written
through the single-layer ``UsdWriter`` and through the clips writer, as ``bench_frames.py``'s
"writing alone" writes them (creation to commit, the same code): frames/s of each, best of
``--repeats``, and their ratio. The clips are of the length ``auto_clips`` would choose (at least
8 chunks, at most about 256 MiB a clip), written by the writer processes ``simulate`` would use
(one per core, at most 8), started before the timed region and given ``--settle`` seconds to
import USD, as ``simulate`` starts them before its set-up (their start is not timed). No GPU is
used.

    python scripts/bench_clips_threshold.py --out docs/caches
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import numpy as np  # noqa: E402

from bench_frames import write_clips, write_one_layer  # noqa: E402  (the "writing alone" code)
from dftl_warp.output import clips as clips_output  # noqa: E402
from dftl_warp.output.clip_pool import cores, writer_count  # noqa: E402
from dftl_warp.usd.read import read_scene  # noqa: E402
from make_scenes import make_default  # noqa: E402

VERTICES = 16


def auto_clip_length(scene, frames: int) -> int:
    """Frames per clip that :func:`auto_clips` chooses for ``frames`` written frames of ``scene``,
    whatever the thresholds (they are lifted while it is asked)."""
    kept = clips_output.AUTO_MIN_POINTS, clips_output.AUTO_MIN_FRAMES
    clips_output.AUTO_MIN_POINTS = clips_output.AUTO_MIN_FRAMES = 0
    try:
        return clips_output.auto_clips(scene, frames, "length.usdc")
    finally:
        clips_output.AUTO_MIN_POINTS, clips_output.AUTO_MIN_FRAMES = kept


def random_frames(scene, frames: int, seed: int) -> list:
    """``frames`` frames of random samples: per prim (points, velocities), float32, stage units."""
    rng = np.random.default_rng(seed)
    return [[(rng.random((c.num_points, 3), dtype=np.float32), rng.random((c.num_points, 3), dtype=np.float32))
             for c in scene.curves] for _ in range(frames)]


def _remove(output: Path) -> None:
    import shutil

    output.unlink(missing_ok=True)
    shutil.rmtree(clips_output.clips_folder(output), ignore_errors=True)


def measure(scene, recorded: list, repeats: int, settle: float, workdir: Path) -> dict:
    """Frames/s (best of ``repeats``) of writing ``recorded`` as one layer and as clips."""
    frames = len(recorded)
    clip_frames = auto_clip_length(scene, frames)
    out = workdir / "out.usdc"
    runs = {"one_layer_fps": [], "clips_fps": []}
    for _ in range(repeats):
        clips_output.start_writers_early(scene, out, clip_frames, frames)  # as simulate does, before its set-up
        time.sleep(settle)
        runs["clips_fps"].append(frames / write_clips(out, scene, recorded, 1, clip_frames))
        _remove(out)
        runs["one_layer_fps"].append(frames / write_one_layer(out, scene, recorded, 1))
        _remove(out)
    return {"points": sum(c.num_points for c in scene.curves), "frames": frames, "clip_frames": clip_frames,
            **{name: max(values) for name, values in runs.items()}, "runs": runs}


def table(rows: list[dict]) -> list[str]:
    lines = ["| points per frame | frames | frames per clip | one layer, frames/s | clips, frames/s | clips / one layer |",
             "|---:|---:|---:|---:|---:|---:|"]
    for r in rows:
        lines.append(f"| {r['points']:,} | {r['frames']} | {r['clip_frames']} | {r['one_layer_fps']:.1f} "
                     f"| {r['clips_fps']:.1f} | {r['clips_fps'] / r['one_layer_fps']:.2f} |")
    return lines


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--points", type=int, nargs="+",
                    default=[16_000, 48_000, 96_000, 160_000, 240_000, 320_000, 480_000, 960_000, 1_600_000],
                    help=f"points per frame (rounded down to whole strands of {VERTICES} vertices)")
    ap.add_argument("--frames", type=int, nargs="+", default=[8, 16, 24, 48], help="written frames")
    ap.add_argument("--repeats", type=int, default=2, help="runs of each; the best counts")
    ap.add_argument("--settle", type=float, default=1.0,
                    help="seconds the writer processes get to start before the clips are timed")
    ap.add_argument("--clip-writers", type=int, default=None,
                    help="clip writer processes (default: one per core, at most 8, as simulate)")
    ap.add_argument("--dir", default=None, help="where the outputs go (default: a temporary folder)")
    ap.add_argument("--out", default=None, help="folder for clips-threshold.md and .json")
    args = ap.parse_args(argv)
    clips_output.WRITERS = args.clip_writers
    writers = args.clip_writers or writer_count()
    load = os.getloadavg()[0]
    started = time.perf_counter()
    rows = []
    if args.dir:
        Path(args.dir).mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(dir=args.dir) as tmp:
        workdir = Path(tmp)
        for points in args.points:
            groom = workdir / f"groom{points}.usda"
            make_default(groom, strands=max(1, points // VERTICES), vertices=VERTICES)
            scene = read_scene(str(groom))
            recorded = random_frames(scene, max(args.frames), seed=points)  # the first N for N frames
            for frames in args.frames:
                rows.append(measure(scene, recorded[:frames], args.repeats, args.settle, workdir))
                print(f"{time.perf_counter() - started:5.0f} s", table(rows[-1:])[-1], file=sys.stderr, flush=True)
            del recorded
    minutes = (time.perf_counter() - started) / 60
    command = "python scripts/bench_clips_threshold.py " + " ".join(argv if argv is not None else sys.argv[1:])
    lines = [f"`{command.strip()}`: {datetime.date.today().isoformat()}, {cores()} cores, {writers} clip writer "
             f"processes, load average {load:.2f} before and {os.getloadavg()[0]:.2f} after, {minutes:.1f} min. "
             f"Random frames (points and velocities) of the default groom, writing alone (creation to commit), "
             f"best of {args.repeats}; clips of the length auto_clips chooses:", "", *table(rows)]
    md = "\n".join(lines)
    print(md)
    if args.out:
        out = Path(args.out)
        out.mkdir(parents=True, exist_ok=True)
        (out / "clips-threshold.md").write_text(md + "\n")
        (out / "clips-threshold.json").write_text(json.dumps({"command": command, "cores": cores(), "writers": writers,
                                                               "rows": rows}, indent=1))


if __name__ == "__main__":
    main()
