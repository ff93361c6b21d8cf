#!/usr/bin/env python3
"""Error against cost of DFTL, the second-order ``rattle`` solver and the reference (issue 19).

The groom: ``--strands`` straight strands of ``--particles`` points, 0.2 m, rooted on a 0.1 m
sphere, released at 45 degrees from hanging (rotated about z around their roots) to swing under
gravity for ``--frames`` frames at 24 fps, roots still. Error: the max over frames of the RMS
position error over all particles, divided by the strand length, against the float64 reference
solver at ``--reference-substeps`` substeps. Cost: the median ms per frame of ``advance`` (device
synchronized) over the frames after the first (which includes compilation and graph capture).

    python scripts/bench_rattle.py --device cuda:0 --strands 100000 --out out/bench_rattle
    python scripts/bench_rattle.py --device cpu --strands 200 --frames 4 --out /tmp/br   # smoke

``--on-chip both`` (the default) runs every rattle setting twice: with the on-chip kernel
(``kernels/solvers/rattle_fused.py``, strands of <= 32 vertices in thread-local storage) and with the
global-memory kernel, and reports the largest position difference between the two
(``vs_global``, stage units; 0 where bitwise equal). ``on``/``off``/``auto`` run one variant.

Prints a markdown table and writes ``bench_rattle.json`` and ``bench_rattle.md`` into ``--out``.
"""

from __future__ import annotations

import argparse
import datetime
import json
import platform
import sys
import time
from pathlib import Path

import numpy as np

#: (label, solver, precision, options, substeps)
SETTINGS = [
    ("DFTL float32", "dftl", "float32", {}, [8, 64, 512]),
    ("rattle float32, 3 Newton", "rattle", "float32", {}, [4, 8, 16]),
    ("rattle float32, 2 Newton", "rattle", "float32", {"newton_iterations": 2}, [8, 16]),
    ("reference float64", "reference", "float64", {}, [8, 16]),
]


def released_groom(strands: int, particles: int, length: float, angle: float = np.pi / 4):
    from dftl_warp.study import scenarios as sc

    pts, counts = sc.groom(strands, particles, length, hanging=True)
    roots = np.repeat(pts[sc.strand_starts(counts)], counts, axis=0)
    c, s = np.cos(angle), np.sin(angle)
    rot = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    return roots + (pts - roots) @ rot.T, counts


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--device", default="cpu")
    p.add_argument("--strands", type=int, default=100_000)
    p.add_argument("--particles", type=int, default=32)
    p.add_argument("--frames", type=int, default=12)
    p.add_argument("--length", type=float, default=0.2)
    p.add_argument("--reference-substeps", type=int, default=64)
    p.add_argument("--out", type=Path, required=True)
    p.add_argument("--on-chip", choices=["both", "on", "off", "auto"], default="both",
                   help="rattle kernel: both variants (default), on chip, global memory, or the solver's choice")
    a = p.parse_args(argv)

    import warp as wp

    wp.config.quiet = True
    wp.init()
    from dftl_warp.core.model import Model
    from dftl_warp.solvers import make_solver
    from dftl_warp.study import scenarios as sc
    from dftl_warp.study.sweeps import max_stretch, trajectory_error

    G = (0.0, -sc.GRAVITY, 0.0)
    pts, counts = released_groom(a.strands, a.particles, a.length)
    rest = np.linalg.norm(np.diff(pts, axis=0), axis=1)

    def run(solver, precision, substeps, options):
        model = Model.from_strands(pts, counts, device=a.device, precision=precision)
        s = make_solver(model, solver, gravity=G, **options)
        clock: list = []
        x, _ = sc.record(s, a.frames, 1 / 24, substeps, clock=clock)
        ms = 1000.0 * float(np.median(clock[1:] if len(clock) > 1 else clock))
        extra = s.diagnostics(s.state()) if solver == "rattle" else {}
        return x, ms, extra

    started = time.perf_counter()
    ref, ref_ms, _ = run("reference", "float64", a.reference_substeps, {})
    variants = {"both": [("global", False), ("on chip", True)], "on": [("on chip", True)],
                "off": [("global", False)], "auto": [(None, None)]}[a.on_chip]
    rows = []
    for label, solver, precision, options, substeps in SETTINGS:
        for k in substeps:
            runs = variants if solver == "rattle" else [(None, None)]
            global_x = None
            for variant, on_chip in runs:
                opts = dict(options) if on_chip is None else {**options, "on_chip": on_chip}
                name = label if variant is None else f"{label}, {variant}"
                x, ms, extra = run(solver, precision, k, opts)
                rows.append({"setting": name, "solver": solver, "precision": precision, "options": opts,
                             "substeps": k, "ms_per_frame": ms, "error": trajectory_error(x, ref, a.length),
                             "max_stretch": float(max_stretch(x, counts, rest).max()),
                             "fallbacks": extra.get("fallbacks"), "finite": bool(np.isfinite(x).all())})
                if on_chip is False:
                    global_x = x
                elif on_chip and global_x is not None:
                    rows[-1]["vs_global"] = float(np.abs(x - global_x).max())
                r = rows[-1]
                diff = f"  vs global {r['vs_global']:.1e}" if "vs_global" in r else ""
                print(f"{name:36s} x{k:<4d} {ms:9.3f} ms/frame  error {r['error']:.2e}  "
                      f"stretch {r['max_stretch']:.1e}{diff}", file=sys.stderr, flush=True)
    device = wp.get_device(a.device)
    meta = {"date": datetime.date.today().isoformat(), "device": a.device, "device_name": device.name,
            "host": platform.node(), "platform": platform.platform(), "warp": wp.config.version,
            "strands": a.strands, "particles": a.particles, "frames": a.frames, "length": a.length,
            "reference_substeps": a.reference_substeps, "on_chip": a.on_chip, "reference_ms_per_frame": ref_ms,
            "seconds": time.perf_counter() - started,
            "command": "python scripts/bench_rattle.py " + " ".join(sys.argv[1:] if argv is None else argv)}
    lines = [f"{a.strands} strands x {a.particles}, released at 45 degrees, {a.frames} frames at 24 fps, "
             f"{meta['device_name']} ({a.device}), {meta['date']}; error against the float64 reference at "
             f"{a.reference_substeps} substeps.", "",
             "| solver | substeps | ms/frame | error | max stretch | vs global |", "|---|---:|---:|---:|---:|---:|"]
    for r in rows:
        diff = f"{r['vs_global']:.1e}" if "vs_global" in r else ""
        lines.append(f"| {r['setting']} | {r['substeps']} | {r['ms_per_frame']:.3g} | {r['error']:.3g} "
                     f"| {r['max_stretch']:.1e} | {diff} |")
    table = "\n".join(lines)
    print(table)
    a.out.mkdir(parents=True, exist_ok=True)
    (a.out / "bench_rattle.json").write_text(json.dumps({"meta": meta, "rows": rows}, indent=1))
    (a.out / "bench_rattle.md").write_text(table + "\n")
    print(json.dumps({"meta": meta, "rows": rows}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
