"""``dftl-warp simulate INPUT -o OUTPUT``: simulate a USD stage's hair, write time samples."""

from __future__ import annotations

import sys

from ..errors import plural


#: the options table's entries offered as flags, in the order ``--help`` lists them
FLAGS = ("start", "end", "substeps", "damping", "correction", "solver", "iterations", "precision",
         "arithmetic", "quality", "device", "prims", "preroll", "tolerance")


def add_parser(sub):
    from ..options import add_arguments
    from ..output.paths import path_argument
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
    p.add_argument("input", metavar="INPUT", type=path_argument("the USD stage to simulate"),
                   help="USD stage (.usd, .usda, .usdc, .usdz)")
    p.add_argument("-o", "--output", required=True, metavar="OUTPUT",
                   type=path_argument("the layer to write, such as out/groom.usdc"),
                   help="output layer (.usdc by default; .usda and .usd allowed)")
    # from the options table (dftl_warp/options.py); the solver names from the live registry
    add_arguments(p, FLAGS, choices={"solver": tuple(SOLVERS)})
    _add_output_flags(p)
    add_arguments(p, ("guides", "guide_method", "guides_output"))   # issue 22: docs/guides.md
    p.add_argument("-q", "--quiet", action="store_true", help="no progress bar or notes (warnings, errors, what --tolerance chose and the summary line are still printed)")
    p.set_defaults(run=run)


def _add_output_flags(p) -> None:
    """The output options of the table (issue 21, docs/caches.md): --frame-step and --check as
    add_arguments makes them, --no-velocities (a switch) and --clips [FRAMES] (optional value)."""
    from ..options import OPTIONS, _cli_type, add_arguments, cli_help

    add_arguments(p, ("frame_step",))
    o = OPTIONS["check"]
    p.add_argument(o.cli, dest="check", default=None, type=_gates, metavar=o.metavar, help=cli_help(o))
    o = OPTIONS["no_velocities"]
    p.add_argument(o.cli, dest="no_velocities", action="store_const", const=True, default=None, help=cli_help(o))
    o = OPTIONS["clips"]
    p.add_argument(o.cli, dest="clips", nargs="?", const=0, default=None, type=_cli_type(o), metavar=o.metavar,
                   help=cli_help(o))
    o = OPTIONS["no_clips"]
    p.add_argument(o.cli, dest="no_clips", action="store_const", const=True, default=None, help=cli_help(o))


def _gates(text):
    import argparse

    from ..errors import UserError
    from ..output.qc import parse_gates

    try:
        parse_gates(text)
    except UserError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None
    return text


def run(args) -> int:
    from ..output.qc import QCError
    from ..simulation.quality import describe_quality, preset_settings
    from ..simulation.simulate import simulate_usd

    notes = _check_flags(args)
    preset = preset_settings(args.quality) if args.quality else {}
    given = {n: getattr(args, n) for n in ("solver", "substeps", "precision", "damping", "correction")}
    for name in given:
        if getattr(args, name) is None and name in preset:
            setattr(args, name, preset[name])
    if args.quality and args.tolerance is None:
        notes.append(describe_quality(args.quality, given))
    try:
        summary = _simulate(args, simulate_usd, notes)
    except QCError as exc:  # a --check gate broken: one line naming the input, exit status 3, no output left
        print(f"dftl-warp: error: {args.input}: {exc}", file=sys.stderr)
        return 3
    s = summary
    for line in _warnings(s, notes, args.quiet):
        print(line, file=sys.stderr)
    for line in s.tolerance:   # --tolerance: what it chose, part of the run's result as the summary line is
        print(f"dftl-warp: {line}", file=sys.stderr)
    total = s.seconds_loading + s.seconds_simulating + s.seconds_writing
    print(
        f"{s.output}: {plural(s.strands, 'strand')}, {plural(s.particles, 'particle')} in {plural(s.prims, 'prim')}, "
        f"{plural(s.frames, 'frame')} ({s.first_frame}..{s.last_frame}); "
        f"loading {s.seconds_loading:.2f} s, simulating {s.seconds_simulating:.2f} s, "
        f"writing {s.seconds_writing:.2f} s, total {total:.2f} s"
    )
    return 0


def _warnings(s, notes: list, quiet: bool) -> list:
    """The warnings printed after the run. Without -q there are none: the notes and every warning
    known before the first frame (the input's, the set-up's, the clean start's: ``s.warnings``) were
    printed before the run, and those raised while stepping as they happened. -q holds back progress
    and notes, never a warning: they all come here, once each."""
    from ..output.progress import is_plain_note, stderr_line

    if not quiet:
        return []
    held = [n for n in notes if n.startswith("dftl-warp: warning: ")]
    held += [stderr_line(w, warning=True) for w in s.warnings if not is_plain_note(w)]
    return held + [stderr_line(w, warning=True) for w in s.run_warnings]


def _check_flags(args) -> list:
    """Flags checked before anything is read: a bad --guides in the guides' own words; and the lines
    (printed with the device line) for flags that do nothing here, so none is ignored silently."""
    from ..guides.scene import parse_count

    if args.guides is not None:
        parse_count(args.guides)
    notes = []
    if args.guide_method is not None and args.guides is None:
        notes.append(f"dftl-warp: warning: --guide-method {args.guide_method} does nothing without --guides (it picks the guides "
                     "--guides asks for; prims with rel dftl:guides name their own)")
    if args.tolerance is not None and args.substeps is not None:
        used = "only the preroll's" if args.preroll else "not used"
        notes.append(f"dftl-warp: warning: --substeps {args.substeps} with --tolerance {args.tolerance:g}: the tolerance "
                     f"chooses the shot's substeps per frame; --substeps is {used}")
    if args.quality and args.tolerance is not None:
        notes.append(f"dftl-warp: warning: --quality {args.quality} with --tolerance {args.tolerance:g}: the tolerance chooses the "
                     "solver and the substeps per frame; the preset gives only its precision, damping and correction")
    return notes


def _simulate(args, simulate_usd, notes):
    return simulate_usd(
        args.input,
        args.output,
        progress=not args.quiet,
        notes=notes,
        start=args.start,
        end=args.end,
        substeps=args.substeps,
        damping=args.damping,
        correction=args.correction,
        solver=args.solver,
        precision=args.precision,
        arithmetic=args.arithmetic,
        iterations=args.iterations,
        device=args.device,
        prims=args.prim,
        preroll=args.preroll,
        no_velocities=args.no_velocities,
        frame_step=args.frame_step,
        check=args.check,
        clips=args.clips,
        no_clips=args.no_clips,
        quality=args.quality,
        command=_command_line(args),
        tolerance=args.tolerance,
        guides=args.guides,
        guide_method=args.guide_method,
        guides_output=args.guides_output,
    )


def _command_line(args) -> str | None:
    import shlex

    argv = getattr(args, "argv", None)
    return None if argv is None else shlex.join(["dftl-warp", *argv])
