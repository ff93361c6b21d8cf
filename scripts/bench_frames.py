#!/usr/bin/env python3
"""Frames end to end: `dftl-warp simulate`'s frame rate against simulating alone and writing alone,
and the value clips' written bytes per second against the disk's (``dd conv=fsync``, same run).

A frame is its substeps, the root update and the device-to-host copy (``Simulation.advance`` +
``Simulation.samples``); writing is authoring its points, velocities and extent into the
streaming .usdc. ``simulate`` overlaps the two (the next frame runs on the device while the host
writes the current one), so its frame rate should approach the slower of the two alone.

Clips (``simulate --clips N``, docs/caches.md): bytes of the output layer and its clips folder
divided by the seconds simulating and writing (commit included), beside ``dd`` writing 1 GiB with
``conv=fsync`` into the same folder (before, between and after the clips; their median: the
2-core VM's virtual disk now and then takes 1 GiB at several times its usual rate). The clips are not
fsync'd by default (nor is the single layer); "+ final fsync" adds the seconds of fsync'ing every
clip file after the run, as ``dd conv=fsync`` does (``--fsync-clips``: the writer processes fsync
each clip as they save it). "clips, writing alone" hands the simulated frames, recorded
beforehand, to the clips writer (its creation and commit included; its writer processes started
before the frames were simulated, as ``simulate`` starts them before its set-up): the clips
pipeline without the simulator, which on a CPU device is the slower part.

    python scripts/bench_frames.py --device cuda:0 --strands 100000 --out DIR
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import warp as wp  # noqa: E402

from dftl_warp.simulation.simulate import Simulation, SimulationOptions, simulate_usd  # noqa: E402
from dftl_warp.usd.read import read_scene  # noqa: E402
from dftl_warp.output import clips as clips_output  # noqa: E402
from dftl_warp.output.clip_pool import cores, writer_count  # noqa: E402
from dftl_warp.output.usd import UsdWriter  # noqa: E402
from make_scenes import make_default  # noqa: E402


def dd_bandwidth(workdir: Path, size_mb: int = 1024) -> float:
    """fsync'd sequential write bandwidth of ``workdir``'s disk, bytes/s (dd conv=fsync)."""
    import re
    import subprocess

    target = workdir / "dd.bin"
    run = subprocess.run(["dd", "if=/dev/zero", f"of={target}", "bs=1M", f"count={size_mb}", "conv=fsync"],
                         capture_output=True, text=True)
    target.unlink(missing_ok=True)
    m = re.search(r"copied, ([0-9.]+) s", run.stderr)
    return size_mb * (1 << 20) / float(m.group(1)) if m else float("nan")


def _tree_bytes(path: Path) -> int:
    return sum(p.stat().st_size for p in ([path] if path.is_file() else path.rglob("*")) if p.is_file())


def _fsync_tree(paths) -> None:
    for path in paths:
        fd = os.open(path, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)


def write_one_layer(out: Path, scene, recorded, first: int) -> float:
    """Seconds to write ``recorded`` (each frame's samples, time codes ``first`` on) as one layer
    through :class:`UsdWriter`, creation to commit ("writing alone")."""
    a = time.perf_counter()
    with UsdWriter.create(out, scene, frames=(first, first + len(recorded) - 1)) as writer:
        for f, frame_samples in enumerate(recorded, start=first):
            writer.write_frame(f, frame_samples)
        writer.commit()
    return time.perf_counter() - a


def write_clips(out: Path, scene, recorded, first: int, clip_frames: int) -> float:
    """Seconds to write ``recorded`` as value clips of ``clip_frames`` frames through the clips
    writer and its writer processes (those started before, else new ones), creation to commit
    ("clips, writing alone"). Returns once the processes have ended (not timed), so that their
    exit does not share the cores with what is timed next."""
    a = time.perf_counter()
    with clips_output.create_clips(out, scene, frames=(first, first + len(recorded) - 1),
                                   clip_frames=clip_frames) as writer:
        for f, frame_samples in enumerate(recorded, start=first):
            writer.write_frame(f, frame_samples)
        pool = getattr(writer, "_pool", None)  # (none in the writer-thread version, 9a270fb)
        processes = [w.process for w in pool.workers] if pool is not None else []
        writer.commit()
    seconds = time.perf_counter() - a
    for process in processes:
        process.wait()
    return seconds


def measure(device: str, strands: int, frames: int, substeps: int, workdir: Path, clip_frames: int = 0) -> dict:
    groom = workdir / "groom.usda"
    make_default(groom, strands=strands, vertices=16)
    first, last = 1, frames
    opts = SimulationOptions(start=first, end=last, substeps=substeps, device=device, solver="dftl")
    scene = read_scene(str(groom))

    # simulating alone (one frame first to compile and capture)
    sim = Simulation(scene, opts, first)
    sim.advance()
    sim.samples()
    sim = Simulation(scene, opts, first)
    a = time.perf_counter()
    for _ in range(frames - 1):
        sim.advance()
        samples = sim.samples()
    t_sim = time.perf_counter() - a
    a = time.perf_counter()
    for _ in range(frames - 1):
        sim.samples()  # the same frame again: transform, device-to-host copy
    t_samples = time.perf_counter() - a

    # writing alone: the simulated frames themselves, each different, as simulate writes them
    clip_frames = clip_frames or max(1, frames // 8)
    if hasattr(clips_output, "start_writers_early"):  # as simulate does before its set-up
        clips_output.start_writers_early(scene, workdir / "alone.usdc", clip_frames, frames)
    sim = Simulation(scene, opts, first)
    recorded = [sim.samples()]  # arrays the caller owns (Simulation.samples copies them)
    for _ in range(frames - 1):
        sim.advance()
        recorded.append(sim.samples())
    out = workdir / "write_only.usdc"
    t_write = write_one_layer(out, scene, recorded, first)
    out.unlink()
    dd_before = dd_bandwidth(workdir)
    t_clips_alone = write_clips(workdir / "alone.usdc", scene, recorded, first, clip_frames)
    alone_bytes = _tree_bytes(workdir / "alone_clips") + _tree_bytes(workdir / "alone.usdc")
    a = time.perf_counter()
    _fsync_tree([workdir / "alone.usdc", *(workdir / "alone_clips").iterdir()])
    t_clips_alone_fsync = t_clips_alone + time.perf_counter() - a
    del recorded
    dd_between = dd_bandwidth(workdir)

    summary = simulate_usd(str(groom), str(workdir / "simulated.usdc"), start=first, end=last,
                           substeps=substeps, device=device, no_clips=True, solver="dftl")  # one layer (no automatic clips)
    t_both = summary.seconds_simulating + summary.seconds_writing
    clips = simulate_usd(str(groom), str(workdir / "clips.usdc"), start=first, end=last, substeps=substeps,
                         device=device, clips=clip_frames, solver="dftl")
    t_clips = clips.seconds_simulating + clips.seconds_writing
    clip_bytes = _tree_bytes(workdir / "clips_clips") + _tree_bytes(workdir / "clips.usdc")
    a = time.perf_counter()
    _fsync_tree([workdir / "clips.usdc", *(workdir / "clips_clips").iterdir()])
    t_clips_fsync = t_clips + time.perf_counter() - a
    dd_after = dd_bandwidth(workdir)
    dd_runs = [dd_before, dd_between, dd_after]
    dd = statistics.median(dd_runs)
    fps = {"simulating alone": (frames - 1) / t_sim, "of which fetching samples alone": (frames - 1) / t_samples,
           "writing alone": frames / t_write, "simulate": frames / t_both,
           f"simulate --clips {clip_frames}": frames / t_clips}
    slower = min(fps["simulating alone"], fps["writing alone"])
    return {"device": device, "strands": summary.strands, "particles": summary.particles, "frames": frames,
            "substeps": substeps, "fps": fps, "of_slower": fps["simulate"] / slower,
            "clip_frames": clip_frames, "clip_writers": clips_output.WRITERS or writer_count(), "cores": cores(),
            "clips_bytes_per_s": clip_bytes / t_clips, "dd_fsync_bytes_per_s": dd, "dd_runs": dd_runs,
            "clips_of_dd": clip_bytes / t_clips / dd, "clips_fsync_bytes_per_s": clip_bytes / t_clips_fsync,
            "clips_fsync_of_dd": clip_bytes / t_clips_fsync / dd, "clips_fsync": bool(getattr(clips_output, "FSYNC", False)),
            "clips_alone_bytes_per_s": alone_bytes / t_clips_alone, "clips_alone_of_dd": alone_bytes / t_clips_alone / dd,
            "clips_alone_fsync_bytes_per_s": alone_bytes / t_clips_alone_fsync,
            "clips_alone_fsync_of_dd": alone_bytes / t_clips_alone_fsync / dd}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--device", default="cpu")
    ap.add_argument("--strands", type=int, default=100_000)
    ap.add_argument("--frames", type=int, default=24)
    ap.add_argument("--substeps", type=int, default=8)
    ap.add_argument("--out", default=None)
    ap.add_argument("--repeats", type=int, default=3, help="independent measurements (the host's load varies)")
    ap.add_argument("--clip-frames", type=int, default=0, help="frames per clip (default: frames / 8)")
    ap.add_argument("--clip-writers", type=int, default=None,
                    help="clip writer processes (default: one per core, at most 8)")
    ap.add_argument("--fsync-clips", action="store_true", help="the clip writers fsync every clip as they save it")
    args = ap.parse_args(argv)
    clips_output.WRITERS = args.clip_writers
    if args.fsync_clips:
        clips_output.FSYNC = True
    wp.config.log_level = wp.LOG_WARNING
    wp.init()
    runs = []
    for _ in range(max(1, args.repeats)):
        with tempfile.TemporaryDirectory() as tmp:
            runs.append(measure(args.device, args.strands, args.frames, args.substeps, Path(tmp), args.clip_frames))
    res = dict(runs[0], runs=runs)
    res["of_slower_median"] = statistics.median(r["of_slower"] for r in runs)
    res["date"] = datetime.date.today().isoformat()
    res["device_name"] = wp.get_device(args.device).name
    names = list(runs[0]["fps"])
    lines = [f"Frames end to end on {res['device_name']} ({args.device}), {res['strands']:,} strands / "
             f"{res['particles']:,} particles, {res['frames']} frames x {res['substeps']} substeps, {res['date']}, "
             f"{len(runs)} measurements in a row (frames/s):", "",
             "| run | " + " | ".join(f"#{k + 1}" for k in range(len(runs))) + " |",
             "|---|" + "---|" * len(runs)]
    lines += [f"| {name} | " + " | ".join(f"{r['fps'][name]:.2f}" for r in runs) + " |" for name in names]
    lines += ["| simulate / slower of the two alone | " + " | ".join(f"{100 * r['of_slower']:.0f}%" for r in runs) + " |"]
    fsynced = "every clip fsync'd" if getattr(clips_output, "FSYNC", False) else "clips not fsync'd"
    lines += ["", f"Value clips of {res['clip_frames']} frames, {res['clip_writers']} writers on {res['cores']} cores, "
              f"{fsynced}; dd: 1 GiB, conv=fsync, same folder, before, between and after the clips (median) (GB/s):", "",
              "| run | " + " | ".join(f"#{k + 1}" for k in range(len(runs))) + " |", "|---|" + "---|" * len(runs)]
    rows = [("dd (fsync'd sequential write), same run", lambda r: f"{r['dd_fsync_bytes_per_s'] / 1e9:.2f}"),
            (f"simulate --clips {res['clip_frames']}", lambda r: f"{r['clips_bytes_per_s'] / 1e9:.2f}"),
            ("simulate --clips / dd", lambda r: f"{100 * r['clips_of_dd']:.0f}%"),
            (f"simulate --clips {res['clip_frames']} + final fsync", lambda r: f"{r['clips_fsync_bytes_per_s'] / 1e9:.2f}"),
            ("simulate --clips + final fsync / dd", lambda r: f"{100 * r['clips_fsync_of_dd']:.0f}%"),
            ("clips, writing alone", lambda r: f"{r['clips_alone_bytes_per_s'] / 1e9:.2f}"),
            ("clips, writing alone / dd", lambda r: f"{100 * r['clips_alone_of_dd']:.0f}%"),
            ("clips, writing alone + final fsync", lambda r: f"{r['clips_alone_fsync_bytes_per_s'] / 1e9:.2f}"),
            ("clips, writing alone + final fsync / dd", lambda r: f"{100 * r['clips_alone_fsync_of_dd']:.0f}%")]
    lines += [f"| {name} | " + " | ".join(cell(r) for r in runs) + " |" for name, cell in rows]
    res["clips_of_dd_median"] = statistics.median(r["clips_of_dd"] for r in runs)
    res["clips_alone_of_dd_median"] = statistics.median(r["clips_alone_of_dd"] for r in runs)
    lines += ["", f"simulate reaches **{100 * res['of_slower_median']:.0f}%** (median) of the slower of simulating "
              f"alone and writing alone; simulate --clips writes **{100 * res['clips_of_dd_median']:.0f}%** of dd "
              f"(median), the clips writing alone **{100 * res['clips_alone_of_dd_median']:.0f}%**."]
    md = "\n".join(lines)
    print(md)
    if args.out:
        out = Path(args.out)
        out.mkdir(parents=True, exist_ok=True)
        tag = args.device.replace(":", "")
        (out / f"frames-{tag}.md").write_text(md + "\n")
        (out / f"frames-{tag}.json").write_text(json.dumps(res, indent=1))


if __name__ == "__main__":
    main()
