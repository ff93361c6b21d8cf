"""``dftl-warp import FILE -o groom.usda``: research hair data (.hair, .data, .tfx, .ply, .bin)
to a USD groom stage the simulator reads. ``docs/import.md`` describes the formats."""

from __future__ import annotations

import sys

from ..errors import plural


def add_parser(sub):
    from ..output.paths import path_argument

    p = sub.add_parser(
        "import",
        help="convert research hair data (.hair, .data, .tfx, strand .ply, CT2Hair .bin) to a USD groom",
        description="Read a hair file (Cem Yuksel's .hair, USC-HairSalon .data, AMD TressFX .tfx, strand PLY, "
                    "CT2Hair .bin) and write a USD stage with a BasisCurves groom (and an optional head collider).",
    )
    p.add_argument("input", metavar="FILE", type=path_argument("the hair file to import"),
                   help="hair file; its format comes from the extension unless --format")
    p.add_argument("-o", "--output", required=True, metavar="OUT",
                   type=path_argument("the stage to write, such as groom.usda"),
                   help="output stage (.usda, .usdc or .usd)")
    p.add_argument("--format", dest="fmt", choices=("hair", "data", "tfx", "ply", "ct2hair"),
                   help="read FILE as this format whatever its extension")
    p.add_argument("--units", metavar="UNIT",
                   help="length unit of FILE: m, cm, mm, um, in, ft or metres per unit "
                        "(default per format: hair cm, data m, tfx m, ply mm, ct2hair mm)")
    p.add_argument("--up-axis", choices=("X", "Y", "Z", "x", "y", "z"), metavar="{X,Y,Z}",
                   help="up axis of FILE (default per format: hair Z, others Y); Y and Z are written as the "
                        "stage's upAxis with the points unchanged, X rotates the points to Y up")
    p.add_argument("--width", type=float, metavar="W",
                   help="hair width in FILE's units, replacing the file's widths (default: the file's, else 80 um)")
    p.add_argument("--head", metavar="MESH", type=path_argument("the head mesh, such as head.obj"), help="head mesh (.obj or .ply, same units and axes) written as a collider")
    p.add_argument("--head-friction", type=float, metavar="MU", help="dftl:friction of the head collider")
    p.add_argument("--max-strands", type=int, metavar="N", help="keep at most N strands, evenly spaced")
    p.add_argument("--every", type=int, metavar="K", help="keep every K-th strand")
    p.add_argument("--segments", type=int, metavar="N", help="resample every strand to N segments by arc length, 1 to 10000")
    p.add_argument("--drop-nonfinite", action="store_true",
                   help="drop strands with NaN/inf points (with a warning) instead of failing")
    p.add_argument("-q", "--quiet", action="store_true", help="no summary line (warnings and errors are still printed)")
    p.set_defaults(run=run)


def run(args) -> int:
    from ..errors import WarningRoute
    from ..importers import GroomImportWarning
    from ..importers.convert import import_groom
    from ..output.paths import created_folders

    # the importer's notes (each names its file) and any other Python warning (numpy's, naming the
    # input): one line each, once, when the groom is written; -q leaves out the summary line, never a
    # warning. The output's missing folders are made as simulate makes them (and gone again on failure)
    with created_folders(args.output), WarningRoute(where=args.input, named=(GroomImportWarning,)) as route:
        result = import_groom(
            args.input, args.output, fmt=args.fmt, units=args.units, up_axis=args.up_axis, width=args.width,
            head=args.head, head_friction=args.head_friction, max_strands=args.max_strands, every=args.every,
            segments=args.segments, drop_nonfinite=args.drop_nonfinite,
        )
    for text in dict.fromkeys(route.held):
        print(f"dftl-warp: warning: {text}", file=sys.stderr)
    if not args.quiet:
        head = ", head collider /Groom/Head" if result.head else ""
        print(f"{result.output}: {plural(result.strands, 'strand')}, {plural(result.points, 'point')} "
              f"from {args.input} "
              f"({result.format}); {result.meters_per_unit:g} m per unit, up axis {result.up_axis}; "
              f"widths {result.widths}{head}")
    return 0
