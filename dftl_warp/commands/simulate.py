"""``dftl-warp simulate INPUT -o OUTPUT``: simulate a USD stage's hair, write time samples."""

from __future__ import annotations

import sys


def add_parser(sub):
    from ..core.precision import PRECISIONS
    from ..simulation.simulate import DEFAULT_SUBSTEPS
    from ..simulation.quality import QUALITY_PRESETS
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
    p.add_argument("--start", type=int, metavar="F", help="first frame (default: the stage's startTimeCode)")
    p.add_argument("--end", type=int, metavar="F", help="last frame, inclusive (default: the stage's endTimeCode)")
    p.add_argument("--substeps", type=_positive_int, metavar="N",
                   help=f"solver steps per frame (default: dftl:substeps, else {DEFAULT_SUBSTEPS})")
    p.add_argument("--damping", type=_unit_float, metavar="S",
                   help="share of the follow-the-leader correction removed from velocities, in [0, 1] (default 1)")
    p.add_argument("--correction", choices=("prior", "posterior"), help="velocity correction form (default prior)")
    p.add_argument("--solver", choices=SOLVERS, help="solver (default dftl)")
    p.add_argument("--iterations", type=_positive_int, metavar="K",
                   help="Gauss-Seidel iterations per step of --solver pbd (default 4)")
    p.add_argument("--precision", choices=PRECISIONS, help="floating-point precision (default float32)")
    p.add_argument("--quality", choices=tuple(QUALITY_PRESETS),
                   help="a measured preset of solver, substeps and precision (docs/accuracy.md); "
                        "explicit flags override its parts")
    p.add_argument("--device", default="cpu",
                   help="cpu or cuda:N (default cpu); a list (cuda:0,cuda:1) splits the strands across devices")
    p.add_argument("--prim", action="append", metavar="PATH",
                   help="simulate only the BasisCurves prims at or below PATH (repeatable)")
    p.add_argument("--quiet", action="store_true", help="no progress bar or warnings")
    p.set_defaults(run=run)


def _positive_int(text):
    import argparse

    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not an integer: {text!r}") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be >= 1, got {value}")
    return value


def _unit_float(text):
    import argparse
    import math

    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
    if not (0.0 <= value <= 1.0) or math.isnan(value):
        raise argparse.ArgumentTypeError(f"must be in [0, 1], got {text}")
    return value


def run(args) -> int:
    from ..simulation.quality import quality_preset
    from ..simulation.simulate import simulate_usd

    preset = quality_preset(args.quality) if args.quality else {}
    for name in ("solver", "substeps", "precision", "damping", "correction"):
        if getattr(args, name) is None and name in preset:
            setattr(args, name, preset[name])
    summary = simulate_usd(
        args.input,
        args.output,
        progress=not args.quiet,
        start=args.start,
        end=args.end,
        substeps=args.substeps,
        damping=args.damping,
        correction=args.correction,
        solver=args.solver,
        precision=args.precision or "float32",
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
