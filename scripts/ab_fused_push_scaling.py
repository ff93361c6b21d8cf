#!/usr/bin/env python3
"""What the scaled push costs the fused substeps: A/B in one process on one device.

Fused DFTL substeps (k = 8 a launch, float32, prior form) of straight strands released under
gravity (``dftl_warp.core.synthetic.uniform_groom``, 2^25 particles in all, or ``N`` given as the
second argument), 32 then 16 particles per strand: *A* the code as it is (the push scaled,
``kernels/solvers/ftl.py``'s ``carried_func``), *A0* the same scaling behind the first push test,
``(x - p) . (x - leader) > 0`` (the kernels of 2026-11-28 before the test became
``|p - leader|^2 < rest^2``), *B* the fused kernel rebuilt with the paper's whole correction
``x - p`` (the kernels ``DFTLSolver(scale_pushes=False)`` builds; this script patches the fused
kernel's function instead, as it was run before that option existed), then *A* again. Each
figure: the median of 7 frames of 8 substeps after a warm-up frame; "per-step" is the per-step
kernel of the same run (with the scaled push; it is memory-bound, docs/benchmarks.md).

    python scripts/ab_fused_push_scaling.py cuda:0
"""
import statistics
import sys
import time

import warp as wp
import dftl_warp as dw
from dftl_warp.core.synthetic import uniform_groom
from dftl_warp.kernels.solvers import fused as F
from dftl_warp.kernels.solvers import ftl
from dftl_warp.kernels.core.arith import norm2, rsqrt
wp.config.quiet = True
dev = sys.argv[1] if len(sys.argv) > 1 else "cuda:0"
G, DT = (0.0, -9.81, 0.0), 1.0 / 240.0
original = ftl.carried_func



def plain(scalar, scale_pushes=True):
    """The paper's whole correction (``scale_pushes`` ignored)."""
    vec3 = wp.types.vector(3, scalar)

    @wp.func
    def carried(x: vec3, p: vec3, leader: vec3, x_old: vec3, rest: scalar):
        return x - p
    return carried



def dot_test(scalar, scale_pushes=True):
    """The scaled push behind the first push test, ``(x - p) . (x - leader) > 0``."""
    vec3 = wp.types.vector(3, scalar)

    @wp.func
    def carried(x: vec3, p: vec3, leader: vec3, x_old: vec3, rest: scalar):
        c = x - p
        if wp.dot(c, x - leader) > scalar(0.0):
            moved2 = norm2(x - x_old)
            c = c * wp.max(scalar(1.0) - moved2 * rsqrt(wp.max(moved2 * (rest * rest), scalar(1.0e-30))),
                           scalar(0.0))
        return c
    return carried


def measure(count, label):
    strands = int(sys.argv[2]) // count if len(sys.argv) > 2 else (1 << 25) // count
    model, state = uniform_groom(strands, count, device=dev)
    control = model.control()
    solver = dw.DFTLSolver(model, gravity=G, fused=True)
    unfused = dw.DFTLSolver(model, gravity=G, fused=False)
    solver.advance(state, control, DT, 8)
    unfused.advance(state, control, DT, 8)
    wp.synchronize()
    def t(s):
        out = []
        for _ in range(7):
            wp.synchronize()
            t0 = time.perf_counter()
            s.advance(state, control, DT, 8)
            wp.synchronize()
            out.append((time.perf_counter() - t0) / 8)
        return statistics.median(out)
    tf, tu = t(solver), t(unfused)
    n = strands * count
    print(f"{label} n={count}: fused {n / tf / 1e9:.1f} G/s, per-step {n / tu / 1e9:.1f} G/s, x{tu / tf:.2f}", flush=True)


for count in (32, 16):
    for label, factory in (("A scaled", original), ("A0 dot test", dot_test), ("B x-p", plain)):
        F.carried_func = factory
        F.fused_step_kernel.cache_clear()
        measure(count, label)
F.carried_func = original
F.fused_step_kernel.cache_clear()
measure(32, "A scaled again")
