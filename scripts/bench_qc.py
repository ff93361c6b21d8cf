#!/usr/bin/env python3
"""What the per-frame QC of a cache costs against the frame it measures (docs/caches.md).

The default scene (3000 strands x 16, a sphere collider), one frame at a time: the simulated frame
(``advance`` and its samples), the QC of the frame (``FrameQC.compute``: the QC kernel and the
penetration kernel, and their read-back), and the penetration kernel alone. Medians of
``--repeats`` frames after one to compile.

    python scripts/bench_qc.py --device cpu
    python scripts/bench_qc.py --device cuda:0 --solver elastic
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
import warp as wp

from dftl_warp.output.qc import FrameQC
from dftl_warp.simulation.simulate import Simulation, SimulationOptions
from dftl_warp.usd.read import read_scene

SCENE = Path(__file__).resolve().parent.parent / "scenes" / "default.usda"


def _median_ms(run, repeats: int, device: str) -> float:
    times = []
    for _ in range(repeats):
        wp.synchronize_device(device)
        a = time.perf_counter()
        run()
        wp.synchronize_device(device)
        times.append(time.perf_counter() - a)
    return 1e3 * float(np.median(times))


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--device", default="cpu")
    ap.add_argument("--solver", default="dftl", help="the groom's solver (default dftl)")
    ap.add_argument("--repeats", type=int, default=5)
    args = ap.parse_args(argv)
    sim = Simulation(read_scene(str(SCENE)), SimulationOptions(device=args.device, solver=args.solver), 1)
    qc = FrameQC(sim)
    sim.advance(), sim.samples(), qc.compute()   # compile

    def frame():
        sim.advance()
        sim.samples()

    part = qc.parts[0]
    frame_ms = _median_ms(frame, args.repeats, args.device)
    qc_ms = _median_ms(qc.compute, args.repeats, args.device)
    depth_ms = _median_ms(lambda: part["depth"].launch(sim.groups[0].state, part["member"], part["penetration"]),
                          args.repeats, args.device) if part["depth"] is not None else float("nan")
    strands = sum(c.num_strands for c in sim.scene.curves)
    print(f"{SCENE.name}, {strands} strands, {args.solver}, {args.device}: simulated frame {frame_ms:.2f} ms; "
          f"QC {qc_ms:.2f} ms ({100 * qc_ms / frame_ms:.1f}% of the frame), of which the penetration kernel "
          f"{depth_ms:.2f} ms (medians of {args.repeats})")


if __name__ == "__main__":
    main()
