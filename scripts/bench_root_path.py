#!/usr/bin/env python3
"""What the C1 root path costs the fused DFTL substeps: frames with root velocities (the Hermite
path, ``Control.set_root_targets(..., velocity_start=...)``) against frames without (the linear
path, which the pipelined kernel specialises away), per strand length (on-chip and pipelined
runs), float32, prior form.

    python scripts/bench_root_path.py --device cuda:0
"""

from __future__ import annotations

import argparse
import statistics
import time

import numpy as np
import warp as wp

import dftl_warp as dw
from dftl_warp.core.layout import strand_offsets


def groom(strands: int, count: int, seed: int = 0):
    rng = np.random.default_rng(seed)
    roots = rng.uniform(-1.0, 1.0, size=(strands, 3))
    pts = roots[:, None, :] + np.arange(count)[None, :, None] * np.array([0.0, -0.01, 0.0])
    return pts.reshape(-1, 3), np.full(strands, count)


def time_frames(solver, state, control, substeps, frames, curved, repeats):
    pts_roots = control.model.points_from_device(state.positions)[strand_offsets(control.model.counts)]
    duration = substeps / 240.0
    v = np.zeros_like(pts_roots)
    v[:, 0] = 0.1
    times = []
    for f in range(frames + repeats):
        start = pts_roots + [0.1 * duration * f, 0.0, 0.0]
        end = pts_roots + [0.1 * duration * (f + 1), 0.0, 0.0]
        if curved:
            control.set_root_targets(start, end, velocity_start=v, velocity_end=1.5 * v, frame_duration=duration)
        else:
            control.set_root_targets(start, end)
        wp.synchronize_device(solver.model.device)
        t = time.perf_counter()
        solver.advance(state, control, 1.0 / 240.0, substeps)
        wp.synchronize_device(solver.model.device)
        if f >= frames:
            times.append(time.perf_counter() - t)
    return statistics.median(times)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--device", default="cuda:0")
    ap.add_argument("--particles", type=int, default=8_000_000, help="particles per groom")
    ap.add_argument("--substeps", type=int, default=8)
    ap.add_argument("--repeats", type=int, default=20)
    args = ap.parse_args(argv)
    wp.config.quiet = True
    wp.init()
    print(f"{wp.get_device(args.device).name}, {args.particles} particles, {args.substeps} substeps per frame, "
          f"float32, prior form; median of {args.repeats} frames")
    print("| particles per strand | fused run | linear path ms/frame | C1 path ms/frame | C1 / linear |")
    print("|---:|---|---:|---:|---:|")
    for count in (32, 64, 128):
        pts, counts = groom(args.particles // count, count)
        with wp.ScopedDevice(args.device):
            model = dw.Model.from_strands(pts, counts, device=args.device)
            solver = dw.DFTLSolver(model, fused=True)
            state, control = solver.state(), model.control()
            linear = time_frames(solver, state, control, args.substeps, 3, False, args.repeats)
            curved = time_frames(solver, state, control, args.substeps, 3, True, args.repeats)
        kind = "pipelined" if solver._pipelined_runs else "on chip"
        print(f"| {count} | {kind} | {linear * 1e3:.3f} | {curved * 1e3:.3f} | {curved / linear:.2f} |")


if __name__ == "__main__":
    main()
