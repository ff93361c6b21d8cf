"""Importers of research hair formats into USD grooms (``dftl-warp import``).

Each format is a :class:`Reader` in :data:`READERS`, found by file extension (or named with
``fmt``); every reader returns a :class:`Groom` in the file's own units and axes, or raises
:class:`~dftl_warp.errors.UserError` with one line naming the file and the byte offset (binary),
line (ASCII) or strand that is wrong. ``docs/import.md`` is the user-facing description.

>>> from dftl_warp.importers import read_groom, import_groom
>>> groom = read_groom("wStraight.hair")
>>> import_groom("wStraight.hair", "groom.usda", units="cm")
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field

import numpy as np

from ..errors import UserError


class GroomImportWarning(UserWarning):
    """Something was approximated or skipped while importing (one warning per kind, with a count)."""


@dataclass
class Groom:
    """Strands as read from a file: concatenated points (N, 3), vertices per strand (S,), optional
    per-vertex widths (N,) or one constant width, all in the file's units."""

    points: np.ndarray
    counts: np.ndarray
    widths: np.ndarray | None = None
    #: one width for every vertex (used when ``widths`` is None)
    constant_width: float | None = None
    #: one-line notes about what the reader approximated or skipped
    warnings: list[str] = field(default_factory=list)
    #: name of the reader
    format: str = ""
    #: each strand's index among the strands the reader returned (kept through subsampling), or None
    strand_ids: np.ndarray | None = None

    @property
    def num_strands(self) -> int:
        return int(self.counts.size)

    @property
    def num_points(self) -> int:
        return int(self.points.shape[0])


@dataclass(frozen=True)
class Reader:
    name: str
    extensions: tuple[str, ...]
    #: ``read(data: bytes, path: str) -> Groom``
    read: object
    #: metres per unit of the format's coordinates when the user gives no ``--units``
    meters_per_unit: float
    #: up axis of the format's coordinates when the user gives no ``--up-axis``
    up_axis: str
    description: str


def _readers() -> dict[str, Reader]:
    from . import ct2hair, cyhair, ply, tressfx, usc_data

    return {r.name: r for r in (cyhair.READER, usc_data.READER, tressfx.READER, ply.READER, ct2hair.READER)}


#: the formats, by name (filled on first use)
READERS: dict[str, Reader] = {}


def readers() -> dict[str, Reader]:
    if not READERS:
        READERS.update(_readers())
    return READERS


def reader_for(path, fmt: str | None = None) -> Reader:
    """The reader named ``fmt``, else the one registered for ``path``'s extension."""
    path = os.fspath(path)
    table = readers()
    if fmt:
        if fmt not in table:
            raise UserError(f"unknown format {fmt!r} (expected one of {', '.join(sorted(table))})")
        return table[fmt]
    ext = os.path.splitext(path)[1].lower()
    for r in table.values():
        if ext in r.extensions:
            return r
    known = ", ".join(sorted(e for r in table.values() for e in r.extensions))
    raise UserError(f"{path}: unknown extension {ext or '(none)'!r}: expected one of {known} (or give --format)")


def read_groom(path, fmt: str | None = None) -> Groom:
    """Read a hair file into a :class:`Groom` (file units and axes; nothing resampled)."""
    from ..errors import check_path
    from ._binary import read_bytes

    check_path("path", path)

    path = os.fspath(path)
    reader = reader_for(path, fmt)
    groom = reader.read(read_bytes(path), path)
    groom.format = reader.name
    return groom


# the conversion pipeline lives in convert.py; re-exported here for callers
def import_groom(*args, **kwargs):
    """See :func:`dftl_warp.importers.convert.import_groom`."""
    from .convert import import_groom as _import_groom

    return _import_groom(*args, **kwargs)


__all__ = ["Groom", "GroomImportWarning", "Reader", "READERS", "readers", "reader_for", "read_groom", "import_groom"]
