# dftl_warp/commands/toy.py
"""``dftl-warp toy``: a toy command (the command recipe of docs/architecture.md)."""

from __future__ import annotations


def add_parser(sub):
    p = sub.add_parser("toy", help="print a toy line", description="Print a toy line.")
    p.add_argument("--name", default="world")
    p.set_defaults(run=run)


def run(args) -> int:
    from ..version import __version__

    print(f"hello {args.name} from dftl-warp {__version__}")
    return 0
