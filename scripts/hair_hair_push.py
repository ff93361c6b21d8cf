#!/usr/bin/env python3
"""How hard the hair-hair repulsion pushes the benchmark groom (``bench_features.groom``) at rest:
the 99th percentile and the largest of ``repulsion h |grad rho|`` over the grid nodes that hold
hair, and the densest node (relative to the rest density: the ``threshold`` that leaves the groom
at rest alone), with the density counting particles (the grid's first form) and relative to the
groom's rest density (``dftl_warp.features.hair_hair``: volume fractions over ``rest_density``),
for each ``--strands``. Numpy on the CPU, the rest positions' trilinear splat on cells of ``--cell``.

    python scripts/hair_hair_push.py --strands 100000 1000000
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_features import groom  # noqa: E402

from dftl_warp.features.hair_hair import DEFAULT_REPULSION, rest_density, splat_nodes, volume_fractions  # noqa: E402


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--strands", type=int, nargs="+", default=[100_000, 1_000_000])
    ap.add_argument("--cell", type=float, default=0.01, help="grid cell (m; the benchmark's 1 cm)")
    ap.add_argument("--width", type=float, default=1e-4, help="hair width (m; the benchmark's 100 um)")
    ap.add_argument("--repulsion", type=float, default=DEFAULT_REPULSION, help="m/s^2 (the default)")
    args = ap.parse_args(argv)
    print("| strands | density | p99 push (m/s^2) | largest push (m/s^2) | densest node |\n|---:|---|---:|---:|---:|")
    for n in args.strands:
        pts, counts, _ = groom(n)
        phi = volume_fractions(pts, counts, args.width, args.cell)
        forms = {"particles per node (before)": np.ones(len(pts)),
                 "relative to the rest density (now)": phi / rest_density(pts, phi, args.cell)}
        for name, weights in forms.items():
            rho = splat_nodes(pts, weights, args.cell)
            push = args.repulsion * np.linalg.norm(np.stack(np.gradient(rho)), axis=0)  # h grad: per cell
            held = push[rho > 0]
            # the densest node in the density's own units (now: the threshold that leaves the groom at rest)
            print(f"| {n} | {name} | {np.percentile(held, 99):.4g} | {held.max():.4g} | {rho.max():.4g} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
