#!/usr/bin/env python3
"""What the scaled push costs: fused DFTL substeps (k = 8 a launch) with ``scale_pushes`` on (the
default) and off (the paper's whole correction), and the per-step kernel, on one device.

Strands of 32 and 16 particles (2^25 particles in all on CUDA), straight, released under gravity
(``dftl_warp.core.synthetic.uniform_groom``); each figure is the median of 7 frames of 8 substeps
after a warm-up frame. The scaled push is ``kernels/solvers/ftl.py``'s ``carried_func``;
docs/accuracy/folded.md says why it is there.

    python scripts/bench_scaled_pushes.py --device cuda:0
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time

import warp as wp

import dftl_warp as dw
from dftl_warp.core.synthetic import uniform_groom

G, DT = (0.0, -9.81, 0.0), 1.0 / 240.0


def particle_steps_per_second(solver, state, control, repeats: int = 7) -> float:
    solver.advance(state, control, DT, 8)
    times = []
    for _ in range(repeats):
        wp.synchronize_device(solver.model.device)
        start = time.perf_counter()
        solver.advance(state, control, DT, 8)
        wp.synchronize_device(solver.model.device)
        times.append((time.perf_counter() - start) / 8)
    return solver.model.num_points / statistics.median(times)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--device", default="cuda:0")
    ap.add_argument("--particles", type=int, default=None, help="particles in all (default 2^25 on CUDA, 2^15 else)")
    args = ap.parse_args(argv)
    wp.config.quiet = True
    total = args.particles or ((1 << 25) if wp.get_device(args.device).is_cuda else (1 << 15))
    print("| particles per strand | kernel | scale_pushes | G particle-steps/s | x per-step kernel |")
    print("|---:|---|---|---:|---:|")
    for count in (32, 16):
        model, state = uniform_groom(total // count, count, device=args.device)
        control = model.control()
        per_step = particle_steps_per_second(dw.DFTLSolver(model, gravity=G, fused=False), state, control)
        print(f"| {count} | per step | on | {per_step / 1e9:.1f} | 1.00 |", flush=True)
        whole = particle_steps_per_second(dw.DFTLSolver(model, gravity=G, fused=False, scale_pushes=False), state,
                                          control)
        print(f"| {count} | per step | off | {whole / 1e9:.1f} | {whole / per_step:.2f} |", flush=True)
        for scale in (True, False):
            fused = dw.DFTLSolver(model, gravity=G, fused=True, scale_pushes=scale)
            rate = particle_steps_per_second(fused, state, control)
            print(f"| {count} | fused, k = 8 | {'on' if scale else 'off'} | {rate / 1e9:.1f} | {rate / per_step:.2f} |",
                  flush=True)
        del model, state
    return 0


if __name__ == "__main__":
    sys.exit(main())
