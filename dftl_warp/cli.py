"""The ``dftl-warp`` command line.

Each command lives in :mod:`dftl_warp.commands` as a module with ``add_parser(subparsers)`` and
``run(args) -> int``. A :class:`~dftl_warp.errors.UserError` ends the program with one line on
stderr and exit status 2, never a traceback.
"""

from __future__ import annotations

import argparse
import importlib
import sys

from .errors import UserError

#: command modules (dftl_warp.commands.<module>), in the order ``--help`` lists them; each module's
#: ``add_parser`` chooses its subcommand's name (``import_groom`` registers ``import``)
COMMANDS = ("simulate", "render", "batch", "study", "info", "devices", "import_groom")


def build_parser() -> argparse.ArgumentParser:
    from . import __version__

    parser = argparse.ArgumentParser(
        prog="dftl-warp",
        description="GPU hair simulation (Dynamic Follow-The-Leader) and rendering with NVIDIA Warp.",
    )
    parser.add_argument("--version", action="version", version=f"dftl-warp {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name in COMMANDS:
        try:
            module = importlib.import_module(f"dftl_warp.commands.{name}")
        except ModuleNotFoundError as exc:
            if exc.name != f"dftl_warp.commands.{name}":
                raise
            continue
        module.add_parser(sub)
    return parser


def main(argv=None) -> int:
    """Entry point of the ``dftl-warp`` console script."""
    from .core.devices import init_warp

    init_warp()
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "run", None):
        parser.print_help()
        return 0
    try:
        return int(args.run(args) or 0)
    except UserError as exc:
        print(f"dftl-warp: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("dftl-warp: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
