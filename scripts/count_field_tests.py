#!/usr/bin/env python3
"""How the deforming body's signed distance field answers the particles' collision tests in the
rows of ``bench_features.py`` that use it: the share answered by the field, and of the others why
they went to the exact mesh query (``kernels/features/sdf.py: WHY_EXACT``).

The kernels are built with ``kernels.features.mesh.COUNT_FIELD_TESTS`` on (each test adds one
to its outcome's counter; a diagnostic, off in every other run). Each row is set up and settled as
in ``bench_features.py``, then its tests are counted over ``--frames`` frames.

    python scripts/count_field_tests.py --device cpu --strands 300
    python scripts/count_field_tests.py --device cuda:0 --strands 1000000 --only "production scene:"

``--patch N`` keeps only the N strands of the ``--strands`` groom whose roots lie nearest the
crown's side (a patch as dense as the whole groom, small enough for the CPU):

    python scripts/count_field_tests.py --device cpu --strands 1000000 --patch 3000 --only "production scene:"
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import warp as wp

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_features import FPS, SETTLE_FRAMES, SUBSTEPS, build_scene, patched_groom, scenarios  # noqa: E402

from dftl_warp.kernels.features import mesh as mesh_kernels  # noqa: E402

#: the rows counted by default (name prefixes of ``bench_features.scenarios``)
DEFAULT_ROWS = ("deforming body mesh (50800 triangles), signed", "production scene")


def count(name, feats, extra, pts, counts, device, frames) -> dict:
    model, solver, state, control = build_scene(pts, counts, feats, extra, device)
    fields = control.features.colliders.kind_data["meshes"].fields
    body = extra["body_frames"]
    dt = 1.0 / FPS / SUBSTEPS
    for f in range(SETTLE_FRAMES + frames):
        if f == SETTLE_FRAMES:
            fields.tests()  # reset: count the frames after settling
        control.features.set_mesh_points(0, body[(f + 1) % len(body)])
        solver.advance(state, control, dt, SUBSTEPS)
    samples = fields.samples()
    return fields.tests(), samples


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--device", default="cpu")
    ap.add_argument("--strands", type=int, default=300)
    ap.add_argument("--frames", type=int, default=12)
    ap.add_argument("--patch", type=int, default=None,
                    help="keep only this many strands of the groom, those rooted nearest one point (its density)")
    ap.add_argument("--only", nargs="*", default=None, help="rows whose names start with one of these "
                    f"(default: {'; '.join(DEFAULT_ROWS)})")
    args = ap.parse_args(argv)
    mesh_kernels.COUNT_FIELD_TESTS = True  # before any kernel is built
    wp.config.quiet = True
    wp.init()
    device = wp.get_device(args.device)
    pts, counts, roots = patched_groom(args.strands, args.patch)
    rows = [r for r in scenarios(pts, counts, roots) if r[0].startswith(tuple(args.only or DEFAULT_ROWS))]
    rows = [r for r in rows if "body_frames" in r[2]]  # the deforming body's rows
    for name, feats, extra in rows:
        with wp.ScopedDevice(device):
            tests, samples = count(name, feats, extra, pts, counts, device, args.frames)
        total = sum(tests.values())
        if not total:
            print(f"{name}: no test of a field (the body collides through exact queries)")
            continue
        size = f"{len(counts)} strands" + (f" (a patch of a {args.strands}-strand groom)" if args.patch else "")
        print(f"{name}: {total} tests in {args.frames} frames of {SUBSTEPS} substeps, {size}", flush=True)
        for why, n in tests.items():
            if n:
                print(f"    {n / total:9.5f}  {why}")
        print(f"    {samples / total:9.5f}  samples of the field per test")
    return 0


if __name__ == "__main__":
    sys.exit(main())
