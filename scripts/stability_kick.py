#!/usr/bin/env python3
"""Do the strands the stability check flags fall, and only they? A groom at a static head, every
free particle kicked by a random velocity, simulated for a few seconds.

The stability check (``dftl_warp/solvers/elastic_stability.py``; ``simulate`` prints its line) flags
the elastic strands whose rest shape is an unstable equilibrium. This script reads a groom the way
``simulate`` does (clean start included), gives every free particle a random velocity of ``--kick``
strand lengths per second (0: none, round-off alone), runs ``--seconds`` at the groom's first frame
(meant for grooms whose head does not move), and counts the strands whose tip ends farther than
``--threshold`` of their length from where it started, among the flagged strands and the others.

    python scripts/stability_kick.py Ratboy_mohawk.usda --kick 0.03 --seconds 4
    python scripts/stability_kick.py Ratboy_mohawk.usda --kick 0 --seconds 10 --threshold 0.01

(docs/elastic.md, "Styles that cannot stand".)
"""

from __future__ import annotations

import argparse
import json
import sys

import numpy as np


def run(path, kick=0.03, seconds=4.0, threshold=0.05, seed=1, device="cpu"):
    """Per elastic group: strands, flagged, tested, and how many of the flagged and of the others fell."""
    import warp as wp

    from dftl_warp.core.layout import strand_offsets
    from dftl_warp.simulation.settings import SimulationOptions
    from dftl_warp.simulation.simulate import Simulation
    from dftl_warp.usd.read import read_scene

    wp.config.quiet = True
    scene = read_scene(str(path))
    first = scene.stage.start_time_code
    sim = Simulation(scene, SimulationOptions(device=device), frame=int(first if first is not None else 1))
    rng = np.random.default_rng(seed)
    rows = []
    for g in sim.groups:
        if g.settings.solver != "elastic":
            continue
        model, state = g.model, g.state
        flagged, _, tested, total = g.solver.unstable_strands()
        counts = np.asarray(model.counts)
        starts = strand_offsets(counts)
        x0 = model.points_from_device(state.positions)
        seg = np.r_[0.0, np.linalg.norm(np.diff(x0, axis=0), axis=1)]
        seg[starts] = 0.0
        length = np.add.reduceat(seg, starts)
        v = rng.normal(size=x0.shape) * kick * np.repeat(length, counts)[:, None]
        v[starts] = 0.0
        state.velocities.assign(model.points_to_device(v, relative=False))
        rows.append(dict(group=g, counts=counts, starts=starts, x0=x0, length=length, flagged=flagged,
                         tested=tested, total=total))
    frames = int(round(seconds * scene.stage.time_codes_per_second))
    for _ in range(frames):
        sim.advance()
    out = []
    for r in rows:
        tips = r["starts"] + r["counts"] - 1
        x = r["group"].model.points_from_device(r["group"].state.positions)
        fell = np.linalg.norm(x[tips] - r["x0"][tips], axis=1) / r["length"] > threshold
        mark = np.zeros(len(r["counts"]), bool)
        mark[r["flagged"]] = True
        out.append(dict(prims=[scene.curves[i].path for i in r["group"].members], strands=int(len(r["counts"])),
                        tested=int(r["tested"]), flagged=int(mark.sum()), flagged_fell=int((fell & mark).sum()),
                        others=int((~mark).sum()), others_fell=int((fell & ~mark).sum())))
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("groom", help="USD stage with elastic hair")
    ap.add_argument("--kick", type=float, default=0.03, help="random particle speed, strand lengths per second")
    ap.add_argument("--seconds", type=float, default=4.0)
    ap.add_argument("--threshold", type=float, default=0.05, help="tip displacement, in strand lengths, that counts as fallen")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--device", default="cpu")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args(argv)
    out = run(args.groom, args.kick, args.seconds, args.threshold, args.seed, args.device)
    if args.json:
        print(json.dumps(out, indent=1))
        return 0
    print("| prims | strands (tested) | kick, L/s | seconds | flagged: fell | others: fell |")
    print("|---|---:|---:|---:|---:|---:|")
    for r in out:
        print(f"| {', '.join(r['prims'])} | {r['strands']} ({r['tested']}) | {args.kick:g} | {args.seconds:g} | "
              f"{r['flagged']}: {r['flagged_fell']} | {r['others']}: {r['others_fell']} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
