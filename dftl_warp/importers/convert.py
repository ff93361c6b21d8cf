"""The import pipeline: read -> check/drop non-finite strands -> subsample -> resample -> widths
-> USD stage (see ``docs/import.md``)."""

from __future__ import annotations

import os
import warnings as _warnings
from dataclasses import dataclass, field

import numpy as np

from ..checks import FLOAT32_MAX
from ..errors import UserError, plural
from ..options import OPTIONS, BadValue, OptionError
from . import Groom, GroomImportWarning, read_groom, reader_for
from ._binary import check_finite
from .scale import head_note, short_note, units_note

#: metres per unit of the names ``--units`` accepts
UNITS = {"m": 1.0, "dm": 0.1, "cm": 0.01, "mm": 0.001, "um": 1e-6, "in": 0.0254, "ft": 0.3048}
#: hair width when the file has none, metres
DEFAULT_WIDTH_M = 80e-6


def parse_units(text) -> float:
    """``m``, ``cm``, ``mm``, ... or a positive number of metres per unit."""
    if isinstance(text, (bool, np.bool_)):
        raise OptionError(f"--units {text!r}: expected one of {', '.join(UNITS)} or metres per unit")
    if isinstance(text, (int, float, np.integer, np.floating)):
        value = float(text)
    else:
        t = str(text).strip().lower()
        if t in UNITS:
            return UNITS[t]
        try:
            value = float(t)
        except ValueError:
            raise OptionError(f"--units {text!r}: expected one of {', '.join(UNITS)} or metres per unit "
                              f"(a positive number)") from None
    if not (np.isfinite(value) and value > 0):
        raise OptionError(f"--units {text!r}: metres per unit must be a positive finite number")
    return value


def parse_up_axis(text) -> str:
    t = str(text).strip().upper()
    if not isinstance(text, str) or t not in ("X", "Y", "Z"):
        raise OptionError(f"--up-axis {text!r}: expected X, Y or Z")
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


def subsample(groom: Groom, every: int | None, max_strands: int | None, notes: list[str], source: str = "") -> Groom:
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
    notes.append(f"{source + ': ' if source else ''}kept {keep.size} of {plural(n, 'strand')} (--every/--max-strands)")
    return select(groom, keep)


def select(groom: Groom, keep: np.ndarray) -> Groom:
    mask = np.zeros(groom.num_strands, dtype=bool)
    mask[keep] = True
    vmask = np.repeat(mask, groom.counts)
    return Groom(groom.points[vmask], groom.counts[mask],
                 widths=None if groom.widths is None else groom.widths[vmask],
                 constant_width=groom.constant_width, warnings=groom.warnings, format=groom.format,
                 strand_ids=None if groom.strand_ids is None else groom.strand_ids[mask])


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
                 constant_width=groom.constant_width, warnings=groom.warnings, format=groom.format,
                 strand_ids=groom.strand_ids)


def coincident_note(source: str, groom: Groom, resampled: bool) -> str | None:
    """One warning for consecutive points of a strand that coincide (as written: float32), which
    the elastic solver refuses (docs/usd.md, "Zero-length segments"); None if there are none."""
    p = np.ascontiguousarray(groom.points, dtype=np.float32)
    if p.shape[0] < 2:
        return None
    same = np.all(p[1:] == p[:-1], axis=1)
    starts = np.cumsum(groom.counts)[:-1]
    same[starts[starts > 0] - 1] = False  # pairs that join the last point of a strand to the next one's first
    if not same.any():
        return None
    owner = np.repeat(np.arange(groom.num_strands), groom.counts)[:-1][same]
    j = int(np.flatnonzero(same)[0])
    k = int(owner[0])
    i = j - int(np.concatenate([[0], starts])[k])
    ids = groom.strand_ids
    strand = f"strand {k}" if ids is None or int(ids[k]) == k else f"strand {int(ids[k])} (curve {k} of /Groom/Hair)"
    n = np.unique(owner).size
    after = " after --segments resampling" if resampled else ""
    return (f"{source}: {strand}: points {i} and {i + 1} coincide{after} (a zero-length segment; {n} of "
            f"{plural(groom.num_strands, 'strand')} {'has' if n == 1 else 'have'} coincident consecutive points); "
            f"kept, but the elastic solver "
            f"(simulate's default for hair with widths) refuses them: simulate with --solver dftl, which "
            f"handles them, or remove the coincident points")


#: the largest float32, USD's point3f and float widths


def check_float32(source: str, points: np.ndarray, counts=None, widths=None, strand_ids=None) -> None:
    """UserError naming the first point (strand and index, or mesh vertex) or width beyond float32,
    which USD would write as inf."""
    big = np.flatnonzero(np.abs(points).max(axis=1, initial=0.0) > FLOAT32_MAX)
    wide = np.flatnonzero(np.abs(widths) > FLOAT32_MAX) if widths is not None and widths.size > 1 else []
    if not len(big) and not len(wide):
        return
    i = int(big[0] if len(big) else wide[0])
    what = f"point {i} = ({', '.join(f'{v:g}' for v in points[i])})" if len(big) else f"width {widths[i]:g} at point {i}"
    if counts is not None:
        starts = np.concatenate([[0], np.cumsum(counts)])
        k = int(np.searchsorted(starts, i, side="right") - 1)
        ids = strand_ids if strand_ids is not None else np.arange(len(counts))
        head = f"strand {int(ids[k])}: " + what.replace(f"point {i}", f"point {i - int(starts[k])}")
    else:
        head = what.replace("point", "vertex")
    raise UserError(f"{source}: {head} does not fit float32 (at most {FLOAT32_MAX:.4g}), the type of USD's "
                    f"points and widths: is the unit right?")


#: the most segments ``--segments`` resamples a strand to: past it a typo (hair has tens to hundreds)
#: that would fill the memory (``--segments 100000000`` ran until killed)
MAX_SEGMENTS = 10_000


def _check_count(name: str, value, low: int = 1, high: int | None = None):
    """An integer option (``max_strands``, ``every``, ``segments``) as an int, or None if unset."""
    if value is None:
        return None
    ok = isinstance(value, (int, np.integer)) and not isinstance(value, (bool, np.bool_))
    if not ok or value < low:
        raise OptionError(f"{name} / --{name.replace('_', '-')} = {value!r}: expected an integer >= {low}")
    if high is not None and value > high:
        raise OptionError(f"{name} / --{name.replace('_', '-')} = {value!r}: expected at most {high}")
    return int(value)


def _check_number(name: str, value, low: float = 0.0, low_open: bool = True):
    """A real-number option (``width``) as a float, or None if unset."""
    if value is None:
        return None
    ok = isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, (bool, np.bool_))
    if not ok or not np.isfinite(value) or (value <= low if low_open else value < low) or abs(value) > FLOAT32_MAX:
        raise OptionError(f"{name} / --{name.replace('_', '-')} = {value!r}: expected a finite number "
                          f"{'>' if low_open else '>='} {low:g} (at most {FLOAT32_MAX:.4g}, USD's float32)")
    return float(value)


def check_head_friction(value):
    """``head_friction`` (the head collider's ``dftl:friction``) checked by the options table's
    ``friction`` option, as ``simulate`` checks the authored attribute; None if unset."""
    if value is None:
        return None
    option = OPTIONS["friction"]
    try:
        return option.check(value)
    except BadValue as exc:
        expected = exc.expected
        if exc.kind == "range" and isinstance(exc.value, float) and not np.isfinite(exc.value):
            expected = f"a finite number {expected}"
        raise OptionError(f"head_friction / --head-friction = {value!r}: {option.usd} must be {expected}") from None


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
        head_friction: its ``dftl:friction``, a finite number >= 0 (checked as ``simulate`` checks it).
        max_strands, every: keep every ``every``-th strand, then at most ``max_strands`` evenly spaced.
        segments: resample every strand to this many segments by arc length.
        drop_nonfinite: drop strands with NaN/inf points (with a warning) instead of failing.

    A bad argument raises :class:`~dftl_warp.options.OptionError` (a ValueError, and a UserError:
    one line and exit status 2 from the command) before anything is read or written.
    Approximations and skipped data are reported with :class:`GroomImportWarning` (one per kind,
    with a count) and listed in the result's ``warnings``.
    """
    from ..errors import check_path
    from .meshes import read_mesh
    from .to_usd import build_stage, check_output, write_stage

    check_path("source", source)
    check_path("output", output)
    source = os.fspath(source)
    output = check_output(output)
    if os.path.abspath(output) == os.path.abspath(source):
        raise UserError(f"{output}: the output would overwrite the input")
    max_strands = _check_count("max_strands", max_strands)
    every = _check_count("every", every)
    segments = _check_count("segments", segments, high=MAX_SEGMENTS)
    width = _check_number("width", width)
    head_friction = check_head_friction(head_friction)
    if not isinstance(drop_nonfinite, (bool, np.bool_)):
        raise OptionError(f"drop_nonfinite = {drop_nonfinite!r}: expected True or False")
    reader = reader_for(source, fmt)
    mpu = reader.meters_per_unit if units is None else parse_units(units)
    axis = reader.up_axis if up_axis is None else parse_up_axis(up_axis)

    groom = read_groom(source, fmt)
    notes = list(groom.warnings)
    total = groom.num_strands
    groom.strand_ids = np.arange(total)
    if head_friction is not None and head is None:
        notes.append(f"{source}: head_friction / --head-friction without a head mesh (--head); ignored")
    if drop_nonfinite:
        finite = np.isfinite(groom.points).all(axis=1)
        if groom.widths is not None:
            finite &= np.isfinite(groom.widths)
        starts = np.concatenate([[0], np.cumsum(groom.counts)])[:-1]
        bad_strand = np.logical_or.reduceat(~finite, starts) if finite.size else np.zeros(0, bool)
        if bad_strand.any():
            notes.append(f"{source}: dropped {int(bad_strand.sum())} of {plural(total, 'strand')} with NaN/inf points")
            groom = select(groom, np.flatnonzero(~bad_strand))
    else:
        check_finite(source, groom.points, groom.counts)
    if groom.num_strands == 0 and total:
        raise UserError(f"{source}: no strands left to import: all {total} have NaN/inf points (--drop-nonfinite)")
    groom = subsample(groom, every, max_strands, notes, source)
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
        every = f"all {groom.num_strands} strands get" if groom.num_strands != 1 else "its 1 strand gets"
        notes.append(f"{source}: no hair widths in the file; {every} {w:g} "
                     f"stage units (80 um; --width sets another)")
    mesh = read_mesh(head) if head is not None else None
    notes.extend(mesh.warnings if mesh is not None else [])
    if axis == "X":
        groom.points = groom.points @ X_UP_TO_Y_UP.T
        if mesh is not None:
            mesh.points = mesh.points @ X_UP_TO_Y_UP.T
        notes.append(f"{source}: X-up input rotated a quarter turn about Z to Y up ((x, y, z) -> (-y, x, z))")
        axis = "Y"
    check_float32(source, groom.points, groom.counts, widths, groom.strand_ids)
    if mesh is not None:
        check_float32(os.fspath(head), mesh.points)
    coincident = coincident_note(source, groom, segments is not None)
    roots = groom.points[np.concatenate([[0], np.cumsum(groom.counts)[:-1]])]
    for note in (coincident, units_note(source, groom.points, groom.counts, mpu, units is not None),
                 short_note(source, groom.points, groom.counts),
                 None if mesh is None else head_note(os.fspath(head), mesh.points, roots)):
        if note:
            notes.append(note)

    for note in notes:
        _warnings.warn(note, GroomImportWarning, stacklevel=2)
    stage = build_stage(groom.points, groom.counts, widths, meters_per_unit=mpu, up_axis=axis, head=mesh,
                        source=source, friction=head_friction)
    write_stage(stage, output)
    return ImportResult(output, reader.name, groom.num_strands, groom.num_points, total, mpu, axis, how,
                        mesh is not None, notes)

