#!/usr/bin/env python3
"""The figures of docs/tolerance.md: ``simulate --tolerance`` on the three scenes of
tests/test_tolerance.py (the falling chain, a groom on a turning head, a groom on a turning head that
is its collider), each at two tolerances a decade apart, against the test's converged references;
then, on the collider scene, DFTL's convergence in float64 (the reference's) and its error in
float32 and float64 at fixed substeps. CPU, one scene after another. ``--per-frame`` runs the
controller without planning ahead (``WINDOW = 1``, no going back) instead.

    python scripts/tolerance_scenes.py [--scenes falling_chain,turning_head,head_with_collider] [--out DIR]
                                       [--per-frame]
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))
import test_tolerance as scenes  # noqa: E402

TOLERANCES = {"falling_chain": (0.01, 0.001), "turning_head": (0.01, 0.001), "head_with_collider": (0.005, 0.0005)}


def dftl(src, out, prim, substeps, precision="float64"):
    from dftl_warp.simulation.simulate import simulate_usd

    simulate_usd(src, out, solver="dftl", damping=1.0, precision=precision, substeps=substeps, device="cpu",
                 monitor=False)
    return scenes.frames(out, prim)


def main() -> int:
    from dftl_warp.output.usd import UsdWriter
    from dftl_warp.simulation.simulate import simulate_usd

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenes", default=",".join(TOLERANCES))
    ap.add_argument("--out", default=None, help="folder for the stages and outputs (default: a temporary one)")
    ap.add_argument("--per-frame", action="store_true", help="no planning ahead: the substeps chosen frame by frame")
    args = ap.parse_args()
    if args.per_frame:
        from dftl_warp.simulation import tolerance

        tolerance.WINDOW, tolerance.LIMIT = 1, float("inf")
    folder = Path(args.out or tempfile.mkdtemp(prefix="tolerance_scenes_"))
    folder.mkdir(parents=True, exist_ok=True)
    print("| scene | tolerance | actual error | actual / tolerance | largest estimate | substeps per frame "
          "| precision | seconds |\n|---|---:|---:|---:|---:|---|---|---:|")
    collider = None
    for name in args.scenes.split(","):
        tolerances = TOLERANCES[name]
        _, prim = scenes.SCENES[name]
        src, ref = scenes.reference(folder, name, tolerances)
        if name == "head_with_collider":
            collider = (src, prim, ref)
        for tol in tolerances:
            out = folder / f"{name}_{tol}.usdc"
            start = time.perf_counter()
            simulate_usd(src, out, tolerance=tol, device="cpu")
            seconds = time.perf_counter() - start
            actual = scenes.error(scenes.frames(out, prim), ref)
            rec = UsdWriter.read_record(out, scenes.RECORD)
            ks = [int(k) for k in rec["group0.substeps"].split()]
            print(f"| {name} | {tol:g} | {actual:.3g} | {actual / tol:.2f} | {rec['group0.max_error']:.3g} "
                  f"| {rec['group0.solver']} {min(ks)}..{max(ks)} (mean {np.mean(ks):.3g}) "
                  f"| {rec.get('group0.precision', '')} | {seconds:.1f} |", flush=True)
    if collider is None or args.per_frame:
        return 0
    src, prim, ref = collider
    print("\nDFTL (s = 1, float64) on the collider scene against 8192 substeps:")
    for k in (512, 1024, 2048, 4096):
        print(f"  {k} substeps: {scenes.error(dftl(src, folder / f'conv{k}.usdc', prim, k), ref):.3g}", flush=True)
    print("\nDFTL (s = 1) on the collider scene at fixed substeps, float32 and float64, against 8192 (float64):")
    for k in (16, 64, 256, 1024):
        row = [scenes.error(dftl(src, folder / f"fixed{k}_{p}.usdc", prim, k, p), ref) for p in ("float32", "float64")]
        print(f"  {k} substeps: float32 {row[0]:.3g}, float64 {row[1]:.3g}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
