#!/usr/bin/env python3
"""Set-up time of elastic strands: reading a generated USD groom (straight strands of 80 um hair
under a turning transform, ``bench_multi_gpu.groom_usd``) and building its ``Simulation`` (the
elastic rest data, inverse statics and the stability test), then the frame loop's ``advance()``.

    python scripts/bench_elastic_setup.py --device cuda:0 --strands 200000,1000000
    python scripts/bench_elastic_setup.py --device cuda:0 --strands 100000 --profile 15

``--profile N`` runs the set-up and the timed frames under cProfile and prints the N functions with
the largest cumulative time of each (the timings then include cProfile's overhead).
"""

from __future__ import annotations

import argparse
import cProfile
import contextlib
import pstats
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--device", default="cpu")
    ap.add_argument("--strands", default="20000", help="groom sizes (comma list)")
    ap.add_argument("--vertices", type=int, default=32)
    ap.add_argument("--frames", type=int, default=8, help="timed advance() frames")
    ap.add_argument("--profile", type=int, default=0, metavar="N", help="print cProfile's top N functions")
    args = ap.parse_args(argv)

    @contextlib.contextmanager
    def profiled(what):
        if not args.profile:
            yield
            return
        prof = cProfile.Profile()
        prof.enable()
        try:
            yield
        finally:
            prof.disable()
            print(f"--- cProfile: {what} (cumulative s)")
            pstats.Stats(prof, stream=sys.stdout).sort_stats("cumulative").print_stats(args.profile)
    import warp as wp

    wp.config.log_level = wp.LOG_WARNING
    wp.config.quiet = True
    wp.init()
    from bench_multi_gpu import groom_usd

    from dftl_warp.simulation.simulate import Simulation, SimulationOptions
    from dftl_warp.usd.read import read_scene

    for n in (int(s) for s in args.strands.split(",")):
        with tempfile.TemporaryDirectory() as tmp:
            path = groom_usd(Path(tmp) / "groom.usdc", n, args.vertices, args.frames + 4, widths=80e-4)
            t = time.perf_counter()
            scene = read_scene(str(path))
            read = time.perf_counter() - t
        t = time.perf_counter()
        with profiled(f"Simulation set-up, {n} strands"):
            sim = Simulation(scene, SimulationOptions(device=args.device, substeps=8, precision="float32"), 1)
        setup = time.perf_counter() - t
        sim.advance()
        sim.samples(owned=False)
        t = time.perf_counter()
        with profiled(f"{args.frames} frames of advance(), {n} strands"):
            for _ in range(args.frames):
                sim.advance()
            wp.synchronize_device(args.device)
        frame = (time.perf_counter() - t) / args.frames
        print(f"{n} elastic strands x {args.vertices}: read {read:.1f} s, Simulation set-up {setup:.1f} s, "
              f"advance {frame * 1e3:.1f} ms/frame", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
