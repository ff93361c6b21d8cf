#!/usr/bin/env python3
"""Where the elastic step's GPU time goes: its frame time under CUDA register caps, and with
straight strands (no frame sweep), against the bare DFTL step in the same run.

The float32-arithmetic kernel's register cap is ``kernels/solvers/elastic.py:
CUDA_MAX_REGISTERS_F32``; each ``--caps`` value rebuilds the kernel with it (0: uncapped). The
groom is ``bench_elastic.py``'s (curly strands, 32 segments, 80 um hair, float32 state).

    python scripts/profile_elastic.py --device cuda:0 --strands 1000000 --caps 0 128 96 64 --out $OUT

Registers and occupancy come from Nsight Compute on one launch, e.g.

    ncu --kernel-name regex:elastic_step --launch-skip 3 --launch-count 1 --section LaunchStats \
        --section Occupancy --section SpeedOfLight --section MemoryWorkloadAnalysis \
        python scripts/profile_elastic.py --device cuda:0 --strands 262144 --caps 0 --repeats 1 --no-straight
"""

from __future__ import annotations

import argparse
import sys
from datetime import date
from pathlib import Path

import numpy as np
import warp as wp

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_elastic import N, curly_groom, time_solver, write_report  # noqa: E402

from dftl_warp.kernels.solvers import elastic as elastic_kernels  # noqa: E402


def straight_groom(strands: int):
    """The curly groom's roots with straight hanging strands of the same 20 cm."""
    pts, counts = curly_groom(strands)
    roots = pts.reshape(strands, N + 1, 3)[:, 0, :]
    s = np.linspace(0.0, 0.2, N + 1)
    one = np.stack([0 * s, -s, 0 * s], -1)
    return (roots[:, None, :] + one[None]).reshape(-1, 3), counts


def frame_time(solver_name, pts, counts, device, substeps, repeats, **options) -> float:
    """Median seconds per frame of ``substeps`` substeps (``bench_elastic.time_solver``)."""
    return time_solver(solver_name, pts, counts, device, substeps, repeats, **options)["frame_s"]


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--device", default="cuda:0")
    ap.add_argument("--strands", type=int, default=1_000_000)
    ap.add_argument("--substeps", type=int, default=8)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--caps", type=int, nargs="+", default=[0, 128, 96, 64],
                    help="CUDA register caps of the float32 kernel (0: none)")
    ap.add_argument("--no-straight", action="store_true", help="skip the straight-strand row")
    ap.add_argument("--out", default=None)
    args = ap.parse_args()
    wp.config.quiet = True
    wp.init()
    curly = curly_groom(args.strands)
    rows = [dict(row="bare DFTL step", frame_s=frame_time("dftl", *curly, args.device, args.substeps, args.repeats))]
    elastic = dict(radius=40e-6, compute_precision="float32")
    default_cap = dict(elastic_kernels.CUDA_MAX_REGISTERS_F32)
    try:
        for cap in args.caps:
            elastic_kernels.CUDA_MAX_REGISTERS_F32.update(dict.fromkeys(default_cap, cap or None))
            elastic_kernels.elastic_kernel.cache_clear()
            label = f"elastic, float32 arithmetic, register cap {cap or 'none'}"
            rows.append(dict(row=label, cap=cap, frame_s=frame_time("elastic", *curly, args.device, args.substeps,
                                                                    args.repeats, **elastic)))
        if not args.no_straight:
            elastic_kernels.CUDA_MAX_REGISTERS_F32.update(default_cap)
            elastic_kernels.elastic_kernel.cache_clear()
            rows.append(dict(row=f"elastic, straight strands (no frame sweep), caps {default_cap}",
                             frame_s=frame_time("elastic", *straight_groom(args.strands), args.device, args.substeps,
                                                args.repeats, **elastic)))
    finally:
        elastic_kernels.CUDA_MAX_REGISTERS_F32.update(default_cap)
        elastic_kernels.elastic_kernel.cache_clear()
    bare = rows[0]["frame_s"]
    lines = [f"Command: `python scripts/profile_elastic.py --device {args.device} --strands {args.strands} "
             f"--caps {' '.join(map(str, args.caps))}`; {date.today()}; {wp.get_device(args.device).name}; "
             f"{args.strands} strands x {N + 1} particles, float32 state, {args.substeps} substeps per frame.", "",
             "| run | ms / frame | x bare DFTL |", "|---|---:|---:|"]
    lines += [f"| {r['row']} | {1e3 * r['frame_s']:.2f} | {r['frame_s'] / bare:.1f} |" for r in rows]
    print("\n".join(lines))
    write_report(args.out, "profile-elastic", args.device, rows, lines)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
