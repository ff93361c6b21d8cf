#!/usr/bin/env python3
"""Where the value-clips writer spends its time (docs/caches.md, "Value clips").

1. The steps of authoring one chunk into a crate layer, as a clip writer process does them
   (``Vt.Vec3fArray.FromNumpy`` per points and velocities array, the extent, ``SetTimeSample``,
   ``Sdf.Layer.Save``, an fsync), each timed, and with the share of its time during which a
   spinning Python thread still ran (on a free core: ~100% when the step releases Python's
   interpreter lock, ~0% when it holds it throughout; two Python threads share it about 50/50).
2. The clips writer itself (``create_clips`` ... ``commit``) on random frames of the same size,
   for each writer count: written GB/s, and CPU seconds per written GB of the frame-loop thread
   (``write_frame``: the copy into shared memory) and of the writer processes (their whole life,
   start included).

    python scripts/profile_clips.py --points 1600000 --frames 24 --clip-frames 3 --writers 1 2
"""

from __future__ import annotations

import argparse
import datetime
import os
import resource
import statistics
import sys
import tempfile
import threading
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

import numpy as np  # noqa: E402
from pxr import Sdf, Usd, UsdGeom, Vt  # noqa: E402


class Spinner:
    """A Python thread counting as fast as it can; :meth:`rate` is its count per second."""

    def __init__(self):
        self.count, self.stop = 0, False
        self.thread = threading.Thread(target=self._spin, daemon=True)
        self.thread.start()

    def _spin(self):
        while not self.stop:
            self.count += 1

    def during(self, fn):
        """(seconds fn took, spinner counts per second meanwhile)"""
        c, a = self.count, time.perf_counter()
        fn()
        dt = time.perf_counter() - a
        return dt, (self.count - c) / dt


def steps(points: int, clip_frames: int, folder: Path, repeats: int) -> list[tuple[str, float, float]]:
    """[(step, ms per call, spinner share)] medians over ``repeats`` chunks."""
    rng = np.random.default_rng(0)
    frames = [(rng.random((points, 3), dtype=np.float32), rng.random((points, 3), dtype=np.float32))
              for _ in range(clip_frames)]
    widths = Vt.FloatArray([0.01])
    spin = Spinner()
    time.sleep(0.2)
    c, a = spin.count, time.perf_counter()
    time.sleep(0.5)
    alone = (spin.count - c) / (time.perf_counter() - a)
    out: dict[str, list] = {}

    def timed(name, fn):
        box = []
        dt, rate = spin.during(lambda: box.append(fn()))
        out.setdefault(name, []).append((dt, rate / alone))
        return box[0]

    for r in range(repeats):
        path = folder / f"chunk{r}.usdc"
        layer = Sdf.Layer.CreateNew(str(path))
        prim = Sdf.CreatePrimInLayer(layer, "/Hair")
        for name, kind in (("points", Sdf.ValueTypeNames.Point3fArray), ("extent", Sdf.ValueTypeNames.Float3Array),
                           ("velocities", Sdf.ValueTypeNames.Vector3fArray)):
            Sdf.AttributeSpec(prim, name, kind)
        for t, (p, v) in enumerate(frames):
            pts = timed("Vt.Vec3fArray.FromNumpy (points)", lambda p=p: Vt.Vec3fArray.FromNumpy(p))
            vel = timed("Vt.Vec3fArray.FromNumpy (velocities)", lambda v=v: Vt.Vec3fArray.FromNumpy(v))
            ext = timed("UsdGeom.Curves.ComputeExtent", lambda pts=pts: UsdGeom.Curves.ComputeExtent(pts, widths))
            timed("3 x SetTimeSample", lambda t=t, values=(pts, vel, ext): [
                layer.SetTimeSample(Sdf.Path(f"/Hair.{name}"), t, value)
                for name, value in zip(("points", "velocities", "extent"), values)])
        timed(f"Sdf.Layer.Save ({clip_frames} frames)", layer.Save)

        def fsync(path=path):
            fd = os.open(path, os.O_RDONLY)
            os.fsync(fd)
            os.close(fd)

        timed("os.fsync of the saved layer", fsync)
        del layer
        path.unlink()
    spin.stop = True
    spin.thread.join()
    return [(name, 1000 * statistics.median(d for d, _ in rs), statistics.median(s for _, s in rs))
            for name, rs in out.items()]


def _scene(path: Path, points: int):
    from dftl_warp.usd.read import read_scene

    stage = Usd.Stage.CreateNew(str(path))
    stage.SetStartTimeCode(1)
    curves = UsdGeom.BasisCurves.Define(stage, "/Hair")
    curves.CreateTypeAttr("linear")
    curves.CreateCurveVertexCountsAttr(Vt.IntArray([16] * (points // 16)))
    pts = np.zeros((points // 16 * 16, 3), np.float32)
    pts[:, 1] = -np.tile(np.arange(16, dtype=np.float32), points // 16)
    pts[:, 0] = np.repeat(np.arange(points // 16, dtype=np.float32), 16)
    curves.CreatePointsAttr(Vt.Vec3fArray.FromNumpy(pts))
    curves.CreateWidthsAttr(Vt.FloatArray([0.01]))
    curves.SetWidthsInterpolation(UsdGeom.Tokens.constant)
    stage.Save()
    return read_scene(str(path))


def pipeline(points: int, frames: int, clip_frames: int, writers: int, folder: Path) -> dict:
    from dftl_warp.output import clip_pool, clips

    scene = _scene(folder / "scene.usda", points)
    n = scene.curves[0].num_points
    rng = np.random.default_rng(1)
    recorded = [[(rng.random((n, 3), dtype=np.float32), rng.random((n, 3), dtype=np.float32))] for _ in range(frames)]
    clips.WRITERS = writers
    children = resource.getrusage(resource.RUSAGE_CHILDREN)
    clip_pool.start_early(writers)
    time.sleep(2.0)  # as simulate starts them before its set-up
    a, loop = time.perf_counter(), 0.0
    with clips.create_clips(folder / "out.usdc", scene, frames=(1, frames), clip_frames=clip_frames) as writer:
        for f, samples in enumerate(recorded, start=1):
            b = time.thread_time()
            writer.write_frame(f, samples)
            loop += time.thread_time() - b
        processes = [w.process for w in writer._pool.workers]
        b = time.thread_time()
        writer.commit()
        loop += time.thread_time() - b
    wall = time.perf_counter() - a
    for p in processes:  # ended: their CPU time is counted once they are waited for
        p.wait()
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    gb = sum(p.stat().st_size for p in [folder / "out.usdc", *(folder / "out_clips").iterdir()]) / 1e9
    return {"writers": writers, "gb_per_s": gb / wall, "frame_loop_cpu_s_per_gb": loop / gb,
            "writers_cpu_s_per_gb": (after.ru_utime + after.ru_stime - children.ru_utime - children.ru_stime) / gb}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--points", type=int, default=1_600_000, help="points per frame (one prim)")
    ap.add_argument("--frames", type=int, default=24)
    ap.add_argument("--clip-frames", type=int, default=3)
    ap.add_argument("--writers", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--dir", default=None, help="where the layers go (default: a temporary folder)")
    args = ap.parse_args(argv)
    print(f"{args.points:,} points per frame ({args.points * 24 / 1e6:.1f} MB with velocities), {os.cpu_count()} CPUs, "
          f"{datetime.date.today().isoformat()}, medians of {args.repeats}", "", sep="\n")
    with tempfile.TemporaryDirectory(dir=args.dir) as tmp:
        rows = steps(args.points, args.clip_frames, Path(tmp), args.repeats)
    print("| step of authoring one chunk | ms | a Python thread ran meanwhile |", "|---|---:|---:|", sep="\n")
    for name, ms, share in rows:
        print(f"| {name} | {ms:.1f} | {100 * share:.0f}% |")
    print("", f"clips writer, {args.frames} random frames in clips of {args.clip_frames} "
          f"(medians of {args.repeats}):", "",
          "| writer processes | GB/s | frame-loop thread, CPU s per GB | writer processes, CPU s per GB |",
          "|---:|---:|---:|---:|", sep="\n")
    for w in args.writers:
        runs = []
        for _ in range(args.repeats):
            with tempfile.TemporaryDirectory(dir=args.dir) as tmp:
                runs.append(pipeline(args.points, args.frames, args.clip_frames, w, Path(tmp)))
        med = {k: statistics.median(r[k] for r in runs) for k in runs[0]}
        print(f"| {w} | {med['gb_per_s']:.2f} | {med['frame_loop_cpu_s_per_gb']:.2f} | "
              f"{med['writers_cpu_s_per_gb']:.2f} |")


if __name__ == "__main__":
    main()
