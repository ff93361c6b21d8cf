#!/usr/bin/env python3
"""Median and 99th-percentile particle speeds (m/s) of the production scene on a dense patch, with
the hair-hair grid rebuilt every substep and every 5 substeps: does a grid rebuilt less often make
the hair move faster (docs/features.md, "Cheaper grids")?

The patch is the ``--patch`` strands of a ``--strands`` groom rooted nearest one point
(``bench_features.patch``), as dense as the whole groom; the scenes are ``bench_features.py``'s
production rows. Speeds every third frame, from the first; the groom settles in the first 12.

    python scripts/hair_hair_patch_speeds.py --device cpu
    python scripts/hair_hair_patch_speeds.py --device cpu --repulsion 0
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
import warp as wp

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_features import FPS, SETTLE_FRAMES, SUBSTEPS, build_scene, patched_groom, scenarios  # noqa: E402

from dftl_warp import features as F  # noqa: E402

ROWS = ("production scene:", "production scene, hair-hair grid rebuilt")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--device", default="cpu")
    ap.add_argument("--strands", type=int, default=1_000_000)
    ap.add_argument("--patch", type=int, default=2000)
    ap.add_argument("--frames", type=int, default=6, help="frames after settling")
    ap.add_argument("--repulsion", type=float, default=None, help="the grid's repulsion (default: the scene's)")
    args = ap.parse_args(argv)
    wp.config.quiet = True
    pts, counts, roots = patched_groom(args.strands, args.patch)
    dt = 1.0 / FPS / SUBSTEPS
    for name, feats, extra in (r for r in scenarios(pts, counts, roots) if r[0].startswith(ROWS)):
        if args.repulsion is not None:
            feats = [F.HairHair(cell_size=f.cell_size, friction=f.friction, repulsion=args.repulsion,
                                splat_interval=f.splat_interval) if isinstance(f, F.HairHair) else f for f in feats]
        with wp.ScopedDevice(args.device):
            model, solver, state, control = build_scene(pts, counts, feats, extra, args.device)
            body = extra["body_frames"]
            speeds = []
            for f in range(SETTLE_FRAMES + args.frames):
                control.features.set_mesh_points(0, body[(f + 1) % len(body)])
                control.features.set_frame_time(f / FPS, (f + 1) / FPS)
                solver.advance(state, control, dt, SUBSTEPS)
                v = np.linalg.norm(state.velocities.numpy(), axis=1)
                speeds.append((f, np.median(v), np.percentile(v, 99)))
        print(f"{name[:70]}: " + "  ".join(f"frame {f}: {a:.3f}/{b:.2f}" for f, a, b in speeds[::3]), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
