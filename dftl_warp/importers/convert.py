"""The import pipeline: read -> check/drop non-finite strands -> subsample -> resample -> widths
-> USD stage (see ``docs/import.md``)."""

from __future__ import annotations

import os
import warnings as _warnings
from dataclasses import dataclass, field

import numpy as np

from ..errors import UserError
from . import Groom, GroomImportWarning, read_groom, reader_for
from ._binary import check_finite

#: metres per unit of the names ``--units`` accepts
UNITS = {"m": 1.0, "dm": 0.1, "cm": 0.01, "mm": 0.001, "um": 1e-6, "in": 0.0254, "ft": 0.3048}
#: hair width when the file has none, metres
DEFAULT_WIDTH_M = 80e-6


def parse_units(text) -> float:
    """``m``, ``cm``, ``mm``, ... or a positive number of metres per unit."""
    if isinstance(text, (int, float)):
        value = float(text)
    else:
        t = str(text).strip().lower()
        if t in UNITS:
            return UNITS[t]
        try:
            value = float(t)
        except ValueError:
            raise UserError(f"--units {text!r}: expected one of {', '.join(UNITS)} or metres per unit "
                            f"(a positive number)") from None
    if not (np.isfinite(value) and value > 0):
        raise UserError(f"--units {text!r}: metres per unit must be a positive finite number")
    return value


def parse_up_axis(text) -> str:
    t = str(text).strip().upper()
    if t not in ("X", "Y", "Z"):
        raise UserError(f"--up-axis {text!r}: expected X, Y or Z")
    return t


#: USD stages are Y- or Z-up: an X-up input is turned a quarter about Z, +X -> +Y (x, y, z) -> (-y, x, z)
X_UP_TO_Y_UP = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])


@dataclass
class ImportResult:
    output: str
    format: str
    strands: int
    points: int
    strands_in_file: int
    meters_per_unit: float
    up_axis: str
    widths: str
    head: bool
    warnings: list[str] = field(default_factory=list)


def subsample(groom: Groom, every: int | None, max_strands: int | None, notes: list[str]) -> Groom:
    n = groom.num_strands
    keep = np.arange(n)
    if every is not None and every > 1:
        keep = keep[::every]
    if max_strands is not None and keep.size > max_strands:
        pick = np.unique(np.linspace(0, keep.size - 1, max_strands).round().astype(np.int64)) if max_strands > 0 \
            else np.zeros(0, np.int64)
        keep = keep[pick]
    if keep.size == n:
        return groom
    notes.append(f"kept {keep.size} of {n} strands (--every/--max-strands)")
    return select(groom, keep)


def select(groom: Groom, keep: np.ndarray) -> Groom:
    mask = np.zeros(groom.num_strands, dtype=bool)
    mask[keep] = True
    vmask = np.repeat(mask, groom.counts)
    return Groom(groom.points[vmask], groom.counts[mask],
                 widths=None if groom.widths is None else groom.widths[vmask],
                 constant_width=groom.constant_width, warnings=groom.warnings, format=groom.format)


def resample(groom: Groom, segments: int) -> Groom:
    """Every strand resampled to ``segments`` segments equally spaced in arc length (piecewise
    linear; widths interpolated alike)."""
    starts = np.concatenate([[0], np.cumsum(groom.counts)])
    m = segments + 1
    out = np.empty((groom.num_strands * m, 3))
    wout = None if groom.widths is None else np.empty(groom.num_strands * m)
    u = np.linspace(0.0, 1.0, m)
    for k in range(groom.num_strands):
        p = groom.points[starts[k]:starts[k + 1]]
        s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(p, axis=0), axis=1))])
        t = u * s[-1]
        for c in range(3):
            out[k * m:(k + 1) * m, c] = np.interp(t, s, p[:, c])
        if wout is not None:
            wout[k * m:(k + 1) * m] = np.interp(t, s, groom.widths[starts[k]:starts[k + 1]])
    return Groom(out, np.full(groom.num_strands, m, dtype=np.int64), widths=wout,
                 constant_width=groom.constant_width, warnings=groom.warnings, format=groom.format)


def import_groom(source, output, *, fmt: str | None = None, units=None, up_axis: str | None = None,
                 width: float | None = None, head=None, head_friction: float | None = None,
                 max_strands: int | None = None, every: int | None = None, segments: int | None = None,
                 drop_nonfinite: bool = False) -> ImportResult:
    """Convert a hair file to a USD groom stage at ``output`` (.usda/.usdc/.usd).

    Args:
        units: the input's length unit (``m``, ``cm``, ``mm``, ... or metres per unit); default the
            format's (see ``READERS``). The stage's metersPerUnit is set to it; points are not scaled.
        up_axis: ``Y`` or ``Z``: the input's up axis, written as the stage's upAxis (points unchanged);
            ``X``: points (and head) rotated to Y up, since USD stages are only Y- or Z-up.
        width: hair width in the input's units; overrides the file's widths. Without it and without
            widths in the file: 80 um.
        head: an OBJ or PLY mesh (same units and axes as the hair) written as a collider Mesh.
        max_strands, every: keep every ``every``-th strand, then at most ``max_strands`` evenly spaced.
        segments: resample every strand to this many segments by arc length.
        drop_nonfinite: drop strands with NaN/inf points (with a warning) instead of failing.

    Approximations and skipped data are reported with :class:`GroomImportWarning` (one per kind,
    with a count) and listed in the result's ``warnings``.
    """
    from .meshes import read_mesh
    from .to_usd import build_stage, check_output, write_stage

    source = os.fspath(source)
    output = check_output(output)
    if os.path.abspath(output) == os.path.abspath(source):
        raise UserError(f"{output}: the output would overwrite the input")
    for name, value, low in (("--max-strands", max_strands, 1), ("--every", every, 1), ("--segments", segments, 1)):
        if value is not None and value < low:
            raise UserError(f"{name} {value}: expected an integer >= {low}")
    if width is not None and not (np.isfinite(width) and width > 0):
        raise UserError(f"--width {width}: expected a positive number")
    reader = reader_for(source, fmt)
    mpu = reader.meters_per_unit if units is None else parse_units(units)
    axis = reader.up_axis if up_axis is None else parse_up_axis(up_axis)

    groom = read_groom(source, fmt)
    notes = list(groom.warnings)
    total = groom.num_strands
    if drop_nonfinite:
        finite = np.isfinite(groom.points).all(axis=1)
        if groom.widths is not None:
            finite &= np.isfinite(groom.widths)
        starts = np.concatenate([[0], np.cumsum(groom.counts)])[:-1]
        bad_strand = np.logical_or.reduceat(~finite, starts) if finite.size else np.zeros(0, bool)
        if bad_strand.any():
            notes.append(f"{source}: dropped {int(bad_strand.sum())} of {total} strands with NaN/inf points")
            groom = select(groom, np.flatnonzero(~bad_strand))
    else:
        check_finite(source, groom.points, groom.counts)
    groom = subsample(groom, every, max_strands, notes)
    if groom.num_strands == 0:
        raise UserError(f"{source}: no strands with 2 or more vertices to import")
    if segments is not None:
        groom = resample(groom, segments)

    if width is not None:
        widths, how = np.array([width], dtype=np.float64), f"constant {width:g} (--width)"
    elif groom.widths is not None:
        widths, how = groom.widths, "per vertex, from the file"
    elif groom.constant_width is not None:
        widths, how = np.array([groom.constant_width]), f"constant {groom.constant_width:g}, from the file"
    else:
        w = DEFAULT_WIDTH_M / mpu
        widths, how = np.array([w]), f"constant {w:g} (80 um)"
        notes.append(f"{source}: no hair widths in the file; all {groom.num_strands} strands get {w:g} "
                     f"stage units (80 um; --width sets another)")
    mesh = read_mesh(head) if head is not None else None
    if axis == "X":
        groom.points = groom.points @ X_UP_TO_Y_UP.T
        if mesh is not None:
            mesh.points = mesh.points @ X_UP_TO_Y_UP.T
        notes.append(f"{source}: X-up input rotated a quarter turn about Z to Y up ((x, y, z) -> (-y, x, z))")
        axis = "Y"

    for note in notes:
        _warnings.warn(note, GroomImportWarning, stacklevel=2)
    stage = build_stage(groom.points, groom.counts, widths, meters_per_unit=mpu, up_axis=axis, head=mesh,
                        source=source, friction=head_friction)
    write_stage(stage, output)
    return ImportResult(output, reader.name, groom.num_strands, groom.num_points, total, mpu, axis, how,
                        mesh is not None, notes)

