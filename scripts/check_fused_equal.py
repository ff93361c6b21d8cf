#!/usr/bin/env python3
"""Check on a device that fused substeps (on chip and pipelined) equal the per-step path bitwise.

A groom of 3000 strands of 1 to 159 vertices (on-chip, pipelined and single-vertex runs mixed),
roots swinging inside every frame on the C1 (Hermite) root path, 3 frames of k substeps, float32 and float64; k = 3 is not a
pipeline width on CUDA and takes the per-step path. Prints one line per case; exits 1 on a
mismatch. The CPU tests check the serial form of the pipeline; this checks the CUDA one.

    python scripts/check_fused_equal.py --device cuda:0
"""

from __future__ import annotations

import argparse
import os
import sys

import numpy as np


import warp as wp  # noqa: E402

import dftl_warp as dw  # noqa: E402
from dftl_warp.core.layout import strand_offsets  # noqa: E402


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--device", default="cuda:0")
    args = ap.parse_args()
    wp.config.quiet = True
    rng = np.random.default_rng(3)
    counts = rng.integers(1, 160, size=3000)
    counts[:5] = [1, 2, 32, 33, 64]
    pts = []
    for n in counts:
        steps = rng.normal(size=(n, 3))
        steps /= np.linalg.norm(steps, axis=1, keepdims=True)
        steps[0] = rng.uniform(-5, 5, 3)
        pts.append(np.cumsum(steps * 0.02, axis=0))
    pts = np.concatenate(pts)
    roots = pts[strand_offsets(counts)]
    ok = True
    for precision in ("float32", "float64"):
        for k in (2, 3, 8, 32):
            out = []
            for fused in (False, True):
                model = dw.Model.from_strands(pts, counts, precision=precision, device=args.device)
                solver = dw.DFTLSolver(model, fused=fused)
                state, control = solver.state(), model.control()
                duration = k / 240  # the frame: k substeps of 1/240 s
                for frame in range(3):
                    offset = lambda a: 0.05 * np.array([np.sin(a), 1 - np.cos(a), 0.3 * a])  # noqa: E731
                    # the root's velocity (units/s): the C1 root path inside the frame (Hermite)
                    rate = lambda a: 0.05 * np.array([np.cos(a), np.sin(a), 0.3]) * 0.7 / duration  # noqa: E731
                    v0, v1 = (np.broadcast_to(rate(a), roots.shape) for a in (0.7 * frame, 0.7 * frame + 0.7))
                    control.set_root_targets(roots + offset(0.7 * frame), roots + offset(0.7 * frame + 0.7),
                                             velocity_start=v0, velocity_end=v1, frame_duration=duration)
                    solver.advance(state, control, 1 / 240, k)
                out.append((model.points_from_device(state.positions),
                            model.points_from_device(state.velocities, relative=False), state.corrections.numpy()))
            equal = all(np.array_equal(a, b) for a, b in zip(*out))
            ok &= equal
            print(f"{precision} k={k}: {len(solver._pipelined_runs)} pipelined runs, "
                  f"{len(solver._fused_runs)} on-chip runs: {'equal' if equal else 'DIFFERENT'}", flush=True)
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
