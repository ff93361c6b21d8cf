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
The groom and the measuring are :mod:`dftl_warp.study.front` (``FrontBench``), which
``dftl-warp study --front`` runs over every solver and setting.
"""

from __future__ import annotations

import argparse
import datetime
import json
import platform
import sys
import time
from pathlib import Path

#: (label, solver, precision, options, substeps)
SETTINGS = [
    ("DFTL float32", "dftl", "float32", {}, [8, 64, 512]),
    ("rattle float32, 3 Newton", "rattle", "float32", {}, [4, 8, 16]),
    ("rattle float32, 2 Newton", "rattle", "float32", {"newton_iterations": 2}, [8, 16]),
    ("reference float64", "reference", "float64", {}, [8, 16]),
]


def released_groom(strands: int, particles: int, length: float, angle: float = 0.7853981633974483):
    """The groom of the front (:func:`dftl_warp.study.front.released_groom`)."""
    from dftl_warp.study.front import released_groom as groom

    return groom(strands, particles, length, angle)


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

    import numpy as np
    import warp as wp

    wp.config.quiet = True
    wp.init()
    from dftl_warp.study.front import FrontBench

    started = time.perf_counter()
    pts, counts = released_groom(a.strands, a.particles, a.length)
    bench = FrontBench(pts, counts, device=a.device, frames=a.frames, length=a.length)
    ref_ms = bench.set_truth(a.reference_substeps)["ms_per_frame"]
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
                frames: list = []
                keep = a.on_chip == "both" and solver == "rattle"
                r = bench.run(solver, precision, k, opts, observe=(lambda f, x: frames.append(x)) if keep else None)
                rows.append({"setting": name, "solver": solver, "precision": precision, "options": opts,
                             "substeps": k, "ms_per_frame": r["ms_per_frame"], "error": r["error"],
                             "max_stretch": r["max_stretch"], "fallbacks": r["fallbacks"], "finite": r["finite"]})
                if on_chip is False:
                    global_x = frames
                elif on_chip and global_x:
                    rows[-1]["vs_global"] = float(max(np.abs(x - g).max() for x, g in zip(frames, global_x)))
                r = rows[-1]
                diff = f"  vs global {r['vs_global']:.1e}" if "vs_global" in r else ""
                print(f"{name:36s} x{k:<4d} {r['ms_per_frame']:9.3f} ms/frame  error {r['error']:.2e}  "
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
