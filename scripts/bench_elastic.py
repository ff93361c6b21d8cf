#!/usr/bin/env python3
"""Time the elastic solver against the bare DFTL step on one device.

A groom of curly strands (32 segments, 80 um hair) in float32; each solver advances frames of
``--substeps`` substeps; the median frame time over ``--repeats`` frames after a warm-up, and the
time per particle-step. Prints a markdown table and writes bench-elastic-<device>.json under --out.

    python scripts/bench_elastic.py --device cuda:0 --strands 1000000 --out DIR
"""

from __future__ import annotations

import argparse
import json
import time
from datetime import date
from pathlib import Path

import numpy as np
import warp as wp

import dftl_warp as dw

N = 32


def curly_groom(strands: int, seed: int = 0):
    """``strands`` helices of 20 cm, 32 equal segments, roots on a 1 m x 1 m grid."""
    rng = np.random.default_rng(seed)
    s = np.linspace(0.0, 0.2, N + 1)
    ang = 2 * np.pi * 3.0 * s / 0.2
    one = np.stack([0.01 * (np.cos(ang) - 1), -s * 0.97, 0.01 * np.sin(ang)], axis=-1)
    side = int(np.ceil(np.sqrt(strands)))
    grid = np.stack(np.meshgrid(np.arange(side), np.arange(side)), -1).reshape(-1, 2)[:strands] / side
    roots = np.c_[grid[:, 0], np.zeros(strands), grid[:, 1]] + rng.normal(0, 1e-4, (strands, 3))
    pts = (roots[:, None, :] + one[None]).reshape(-1, 3)
    return pts, np.full(strands, N + 1)


def time_solver(name, pts, counts, device, substeps, repeats, **options):
    model = dw.Model.from_strands(pts, counts, device=device, precision="float32")
    solver = dw.make_solver(model, name, **options)
    state, control = solver.state(), model.control()
    dt = 1.0 / (24 * substeps)
    solver.advance(state, control, dt, substeps)  # compile and capture
    wp.synchronize_device(device)
    times = []
    for _ in range(repeats):
        t = time.perf_counter()
        solver.advance(state, control, dt, substeps)
        wp.synchronize_device(device)
        times.append(time.perf_counter() - t)
    frame = float(np.median(times))
    return {"solver": name, "frame_s": frame, "ns_per_particle_step": frame / (substeps * pts.shape[0]) * 1e9}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--device", default="cpu")
    ap.add_argument("--strands", type=int, default=2000)
    ap.add_argument("--substeps", type=int, default=8)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--out", default=None)
    args = ap.parse_args()
    wp.config.quiet = True
    wp.init()
    pts, counts = curly_groom(args.strands)
    rows = [time_solver("dftl", pts, counts, args.device, args.substeps, args.repeats)]
    for compute in ("float32", "float64"):
        r = time_solver("elastic", pts, counts, args.device, args.substeps, args.repeats, radius=40e-6,
                        compute_precision=compute)
        r["solver"] = f"elastic ({compute} arithmetic)"
        rows.append(r)
    base = rows[0]["frame_s"]
    lines = [f"Command: `python scripts/bench_elastic.py --device {args.device} --strands {args.strands} "
             f"--substeps {args.substeps}`; {date.today()}; device {wp.get_device(args.device).name}; "
             f"{args.strands} curly strands x {N + 1} particles, float32 state.", "",
             "| solver | ms / frame | ns / particle-step | x DFTL |", "|---|---:|---:|---:|"]
    lines += [f"| {r['solver']} | {1e3 * r['frame_s']:.2f} | {r['ns_per_particle_step']:.3f} | "
              f"{r['frame_s'] / base:.1f} |" for r in rows]
    print("\n".join(lines))
    write_report(args.out, "bench-elastic", args.device, rows, lines)
    return 0


def write_report(out_dir, stem: str, device: str, rows, lines) -> None:
    """``<stem>-<device>.json`` (the rows) and ``.md`` (the report ``lines``) under ``out_dir``
    (nothing when it is None)."""
    if out_dir:
        out = Path(out_dir)
        out.mkdir(parents=True, exist_ok=True)
        tag = device.replace(":", "")
        (out / f"{stem}-{tag}.json").write_text(json.dumps(rows, indent=1))
        (out / f"{stem}-{tag}.md").write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    raise SystemExit(main())
