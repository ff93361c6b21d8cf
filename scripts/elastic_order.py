#!/usr/bin/env python3
"""The elastic solver's convergence order against a fine-step run of itself: the ``p`` of
``--tolerance``'s Richardson factor ``1 / (1 - 2^-p)`` (``ORDER["elastic"]`` in
dftl_warp/simulation/tolerance_sample.py; docs/tolerance.md).

Step doubling estimates the error of a run at ``k`` substeps from its difference to a run at
``2 k``; what it needs is the order at which the solver converges to its own limit (not to another
solver's: docs/elastic/convergence.md measures that). Error: the max over the 24 fps frames of the
RMS position error over particles (m), against the same solver at ``--fine`` substeps per frame.

The scenarios (80 um hair, float64, one strand, 16 segments, 0.5 s):

- *swinging*: a straight strand 0.1 m long (twice its bending length) released horizontal, root
  held: it swings down and back;
- *shaken curl*: a styled helix (0.2 m, two turns of 1.5 cm radius) hanging as authored (inverse
  statics), its root shaken 2 cm at 2 Hz;
- *turning*: the swinging strand's root and clamp turned about the vertical through a point 5 cm
  away (0 -> 40 -> -20 degrees over the 12 frames), as a head turning under ``--tolerance``.

``--usd`` measures the same on the groom of tests/test_tolerance_elastic.py (12 strands of 80 um
hair, 0.15 m, on a turning head; elastic by default), through ``simulate_usd``, against 2048
substeps in float64, then runs ``--tolerance`` at a few tolerances against that reference.

    python scripts/elastic_order.py                       # about a minute on 2 cores
    python scripts/elastic_order.py --substeps 4 8 16 --fine 1024
    python scripts/elastic_order.py --usd                 # about a minute
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

FRAMES = 12
FRAME = 1.0 / 24.0
SEGMENTS = 16


def _yaw(degrees: float) -> np.ndarray:
    a = np.radians(degrees)
    return np.array([[np.cos(a), 0.0, np.sin(a)], [0.0, 1.0, 0.0], [-np.sin(a), 0.0, np.cos(a)]])


def _turn(frame: float) -> float:
    """Degrees at ``frame`` (0..12): 0 -> 40 at frame 5 -> -20 at frame 11, piecewise linear."""
    return float(np.interp(frame, [0.0, 5.0, 11.0, 12.0], [0.0, 40.0, -20.0, -20.0]))


def scenario(name: str):
    """(rest points, solver options, drive(solver, control, f) or None)."""
    from dftl_warp.study import scenarios as sc

    if name == "shaken curl":
        rest = sc.hair_helix(segments=SEGMENTS)
        roots = sc.shaken_roots(rest[:1])

        def drive(solver, control, f):
            control.set_root_targets(roots(f * FRAME), roots((f + 1) * FRAME))
        return rest, {}, drive
    rest = sc.hair_cantilever(0.1, SEGMENTS)
    if name == "swinging":
        return rest, {"inverse_statics": False}, None
    centre = np.array([0.05, 0.0, 0.0])

    def drive(solver, control, f):
        rot = [_yaw(_turn(f)), _yaw(_turn(f + 1))]
        root = [(r @ (rest[:1] - centre).T).T + centre for r in rot]
        control.set_root_targets(root[0], root[1])
        ghosts = [(r @ (solver.authored_clamps - centre).T).T + centre for r in rot]
        solver.set_clamp_targets(ghosts[0], ghosts[1], rotation_start=rot[0][None], rotation_end=rot[1][None])
    return rest, {"inverse_statics": False}, drive


def run(name: str, substeps: int) -> np.ndarray:
    """Positions (frames + 1, N, 3) of the scenario at ``substeps`` per frame."""
    from dftl_warp.core.model import Model
    from dftl_warp.solvers import make_solver
    from dftl_warp.study import scenarios as sc

    rest, options, drive = scenario(name)
    model = Model.from_strands(rest, [rest.shape[0]], device="cpu", precision="float64")
    solver = make_solver(model, "elastic", gravity=(0.0, -sc.GRAVITY, 0.0), radius=sc.HAIR_RADIUS, **options)
    state, control = solver.state(), model.control()
    out = [model.points_from_device(state.positions)]
    for f in range(FRAMES):
        if drive is not None:
            drive(solver, control, f)
        solver.advance(state, control, FRAME / substeps, substeps)
        out.append(model.points_from_device(state.positions))
    return np.stack(out)


def error(x, ref) -> float:
    return float(np.sqrt(((x - ref) ** 2).sum(-1).mean(-1)).max())


def usd(folder: Path, substeps, tolerances) -> None:
    """Fixed substeps, then ``--tolerance``, on the groom of tests/test_tolerance_elastic.py."""
    from dftl_warp.output.usd import UsdWriter
    from dftl_warp.simulation.simulate import simulate_usd
    from dftl_warp.simulation.tolerance import RECORD

    sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))
    import test_tolerance_elastic as scenes

    src = scenes.turning_groom(folder / "in.usda")
    simulate_usd(src, folder / "ref.usdc", substeps=2048, precision="float64", device="cpu", monitor=False)
    ref = scenes.frames(folder / "ref.usdc")
    print("| k | error(k) | error(k) / abs(x_k - x_2k) |\n|---:|---:|---:|")
    runs = {}
    for k in sorted(set(substeps) | {2 * k for k in substeps}):
        simulate_usd(src, folder / f"k{k}.usdc", substeps=k, device="cpu", monitor=False)
        runs[k] = scenes.frames(folder / f"k{k}.usdc")
    for k in sorted(substeps):
        e = error(runs[k], ref)
        print(f"| {k} | {e:.3g} | {e / error(runs[k], runs[2 * k]):.2f} |")
    print("\n| tolerance | actual error | actual / tolerance | largest estimate | substeps per frame | precision "
          "| seconds |\n|---:|---:|---:|---:|---|---|---:|")
    for tol in tolerances:
        start = time.perf_counter()
        simulate_usd(src, folder / "tol.usdc", tolerance=tol, device="cpu")
        seconds = time.perf_counter() - start
        actual = error(scenes.frames(folder / "tol.usdc"), ref)
        rec = UsdWriter.read_record(folder / "tol.usdc", RECORD)
        ks = [int(k) for k in rec["group0.substeps"].split()]
        print(f"| {tol:g} | {actual:.3g} | {actual / tol:.2f} | {rec['group0.max_error']:.3g} | "
              f"{rec['group0.solver']} {min(ks)}..{max(ks)} (mean {np.mean(ks):.3g}) | {rec['group0.precision']} "
              f"| {seconds:.1f} |")


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--substeps", type=int, nargs="+", default=[2, 4, 8, 16, 32, 64, 128])
    ap.add_argument("--fine", type=int, default=4096)
    ap.add_argument("--scenarios", nargs="+", default=["swinging", "shaken curl", "turning"])
    ap.add_argument("--usd", action="store_true", help="the groom of tests/test_tolerance_elastic.py instead")
    ap.add_argument("--tolerances", type=float, nargs="+", default=[0.02, 0.01, 0.005, 0.002, 0.001])
    args = ap.parse_args(argv)
    if args.usd:
        usd(Path(tempfile.mkdtemp(prefix="elastic_order_")), args.substeps, args.tolerances)
        return
    print("| scenario | k | error(k) | order(k -> 2k) | error(k) / abs(x_k - x_2k) | p it implies |")
    print("|---|---:|---:|---:|---:|---:|")
    for name in args.scenarios:
        ref = run(name, args.fine)
        ks = sorted(args.substeps)
        runs = {k: run(name, k) for k in ks + [2 * ks[-1]]}
        for k in ks:
            e, e2 = error(runs[k], ref), error(runs[2 * k], ref)
            ratio = e / error(runs[k], runs[2 * k])
            implied = -np.log2(1.0 - 1.0 / ratio) if ratio > 1 else float("inf")
            print(f"| {name} | {k} | {e:.3g} | {np.log2(e / e2):.2f} | {ratio:.2f} | {implied:.2f} |")


if __name__ == "__main__":
    main()
