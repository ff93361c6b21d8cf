#!/usr/bin/env python3
"""Check, on a CUDA device, that the per-strand splat with warp-aggregated node writes
(``kernels/features/grid_aggregate.py``) puts the right density and momentum on the grid, and
time it beside the per-particle splat and the per-strand splat without aggregation.

The CPU tests cannot see the aggregation (on the CPU each thread writes its own values). The
groom is ``bench_features.py``'s after ``--frames`` frames of falling under gravity (so strands
of one warp have spread over several cells), with 1 cm and 4 cm cells. The error of each splat is
the largest difference of a node's density (or momentum) from the same sums in float64 (numpy),
over the largest such value. Pass: the aggregated splat's error is below ``--tolerance`` or no
larger than the per-particle splat's (float32 atomics summing up to a million values per node
round by more). Exit status 1 otherwise.

    python scripts/check_splat_aggregate.py --device cuda:0 --strands 1000000
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
import warp as wp

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_features import FPS, G, SUBSTEPS, groom  # noqa: E402

import dftl_warp as dw  # noqa: E402
from dftl_warp import features as F  # noqa: E402
from dftl_warp.kernels.features.grid_strands import grid_splat_strands_kernel  # noqa: E402


def reference(x, v, lower, cell, shape):
    """Density and momentum of particles ``x`` (N, 3) m with velocities ``v`` in float64 (numpy),
    on the grid of lower corner ``lower`` and node counts ``shape`` (as ``grid_cell``: node 0 one
    cell below ``lower``)."""
    g = (x.astype(np.float64) - lower.astype(np.float64)) / cell + 1.0
    ijk = np.floor(g).astype(np.int64)
    f = g - ijk
    ok = np.all((ijk >= 0) & (ijk < np.array(shape) - 1), axis=1)
    ijk, f, v = ijk[ok], f[ok], v[ok].astype(np.float64)
    size = int(np.prod(shape))
    density = np.zeros(size)
    momentum = np.zeros((size, 3))
    for c in range(8):
        d = np.array([c & 1, (c >> 1) & 1, (c >> 2) & 1])
        w = np.prod(np.where(d == 1, f, 1.0 - f), axis=1)
        node = np.ravel_multi_index((ijk + d).T, shape)
        density += np.bincount(node, weights=w, minlength=size)
        for a in range(3):
            momentum[:, a] += np.bincount(node, weights=w * v[:, a], minlength=size)
    return density.reshape(shape), momentum.reshape(*shape, 3)


def timed_ms(fn, device, repeats=10) -> float:
    """Milliseconds of one call of ``fn`` (the fastest of ``repeats``)."""
    best = float("inf")
    for _ in range(repeats):
        wp.synchronize_device(device)
        t = time.perf_counter()
        fn()
        wp.synchronize_device(device)
        best = min(best, time.perf_counter() - t)
    return best * 1e3


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--device", default="cuda:0")
    ap.add_argument("--strands", type=int, default=100_000)
    ap.add_argument("--frames", type=int, default=6)
    ap.add_argument("--tolerance", type=float, default=1e-5)
    args = ap.parse_args(argv)
    wp.config.quiet = True
    wp.init()
    device = wp.get_device(args.device)
    if not device.is_cuda:
        print(f"check_splat_aggregate.py: {args.device} is not a CUDA device", file=sys.stderr)
        return 2
    pts, counts, _ = groom(args.strands)
    failed = False
    for cell in (0.01, 0.04):
        with wp.ScopedDevice(device):
            model = dw.Model.from_strands(pts, counts, device=device, features=[F.HairHair(cell_size=cell)])
            solver = dw.DFTLSolver(model, gravity=G, fused=False)
            state, control = solver.state(), model.control()
            for _ in range(args.frames):
                solver.advance(state, control, 1.0 / FPS / SUBSTEPS, SUBSTEPS)
            grid = solver._features._grid
            g = grid.arrays
            pos, vel = state.positions, state.velocities
            grid.bounds(pos)
            plain = grid_splat_strands_kernel(model.scalar, False, aggregate=False)

            def strands_plain():
                g["density"].zero_()
                g["momentum"].zero_()
                wp.launch(plain, dim=model.num_strands, inputs=[model.strand_base, model.strand_stride,
                          model.strand_count, pos, vel, g["lower"], 1.0 / grid.cell, 0.0, *grid.shape],
                          outputs=[g["density"], g["momentum"]])

            def variant(by_strands):
                def run():
                    grid.by_strands = by_strands
                    grid.splat(pos, vel)
                return run

            out = {}
            for name, fn in (("per particle", variant(False)), ("per strand", strands_plain),
                             ("per strand, aggregated", variant(True))):
                ms = timed_ms(fn, device)
                out[name] = (g["density"].numpy().astype(np.float64), g["momentum"].numpy().astype(np.float64), ms)
            ref_d, ref_m = reference(model.points_from_device(pos), model.points_from_device(vel),
                                     g["lower"].numpy(), grid.cell, grid.shape)
        errors = {}
        for name, (d, m, ms) in out.items():
            errors[name] = max(float(np.abs(d - ref_d).max() / np.abs(ref_d).max()),
                               float(np.abs(m - ref_m).max() / np.abs(ref_m).max()))
        agg = errors["per strand, aggregated"]
        ok = agg <= max(args.tolerance, errors["per particle"])
        failed |= not ok
        print(f"{args.strands} strands, {cell * 100:g} cm cells, {int(np.prod(grid.shape))} nodes, "
              f"{ref_d.sum():.8g} particles on the grid: " + "; ".join(
                  f"{name} {ms:.3f} ms, error {errors[name]:.2e}" for name, (_, _, ms) in out.items())
              + f": {'ok' if ok else 'FAILED'}", flush=True)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
