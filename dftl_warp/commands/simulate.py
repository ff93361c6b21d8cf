"""``dftl-warp simulate INPUT -o OUTPUT``: simulate a USD stage's hair, write time samples."""

from __future__ import annotations

import sys


#: the options table's entries offered as flags, in the order ``--help`` lists them
FLAGS = ("start", "end", "substeps", "damping", "correction", "solver", "iterations", "precision",
         "quality", "device", "prims")


def add_parser(sub):
    from ..options import add_arguments
    from ..solvers import SOLVERS

    p = sub.add_parser(
        "simulate",
        help="simulate the hair (BasisCurves) of a USD stage and write the result as USD",
        description=(
            "Simulate every UsdGeom.BasisCurves prim of INPUT (vertex 0 of each curve is its root) "
            "and write OUTPUT: a layer that sublayers INPUT and adds time-sampled points, "
            "velocities and extent for each frame. Per-prim dftl: attributes (see docs/usd.md) "
            "apply where no flag is given."
        ),
    )
    p.add_argument("input", metavar="INPUT", help="USD stage (.usd, .usda, .usdc, .usdz)")
    p.add_argument("-o", "--output", required=True, metavar="OUTPUT",
                   help="output layer (.usdc by default; .usda and .usd allowed)")
    # from the options table (dftl_warp/options.py); the solver names from the live registry
    add_arguments(p, FLAGS, choices={"solver": tuple(SOLVERS)})
    p.add_argument("--quiet", action="store_true", help="no progress bar or warnings")
    p.set_defaults(run=run)


def run(args) -> int:
    from ..simulation.quality import describe_quality, quality_preset
    from ..simulation.simulate import simulate_usd

    preset = quality_preset(args.quality) if args.quality else {}
    given = {n: getattr(args, n) for n in ("solver", "substeps", "precision", "damping", "correction")}
    for name in given:
        if getattr(args, name) is None and name in preset:
            setattr(args, name, preset[name])
    summary = simulate_usd(
        args.input,
        args.output,
        progress=not args.quiet,
        notes=[describe_quality(args.quality, given)] if args.quality else [],
        start=args.start,
        end=args.end,
        substeps=args.substeps,
        damping=args.damping,
        correction=args.correction,
        solver=args.solver,
        precision=args.precision,
        iterations=args.iterations,
        device=args.device,
        prims=args.prim,
    )
    if not args.quiet:
        for w in summary.warnings:
            print(f"dftl-warp: warning: {w}", file=sys.stderr)
    s = summary
    total = s.seconds_loading + s.seconds_simulating + s.seconds_writing
    print(
        f"{s.output}: {s.strands} strands, {s.particles} particles in {s.prims} prim(s), "
        f"{s.frames} frames ({s.first_frame}..{s.last_frame}); "
        f"loading {s.seconds_loading:.2f} s, simulating {s.seconds_simulating:.2f} s, "
        f"writing {s.seconds_writing:.2f} s, total {total:.2f} s"
    )
    return 0
