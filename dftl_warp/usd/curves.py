"""Checks of BasisCurves data shared by the simulation's reader and the renderer's: plain numpy,
no USD objects.

- :func:`check_vertex_counts`: every curve has as many control points as its type, basis and
  wrap need (a nonperiodic bezier curve 3n + 1, n >= 1; bspline and catmullRom at least 4, or 2
  when pinned);
- :func:`curve_spans` and :func:`primvar_count`: how many values each primvar interpolation needs;
- :func:`check_primvar`: a primvar's (e.g. ``widths``) value count for its interpolation, finite
  values and, for widths, no negative one and none too large (:func:`~dftl_warp.checks.check_lengths`);
- :func:`note_single_vertex`: one warning naming the curves of a single vertex.

Messages name the file, the prim and the index: ``FILE: PRIM: widths: 3 values for 'vertex'
interpolation, expected 5``.
"""

from __future__ import annotations

import numpy as np

from ..checks import check_lengths
from ..errors import UserError, plural

#: control points from one cubic span to the next
CUBIC_VSTEP = {"bezier": 3, "bspline": 1, "catmullRom": 1}


def note_single_vertex(counts, where: str, warnings: list) -> None:
    """One warning naming the curves of a single vertex (a root without a segment: nothing to
    simulate or draw)."""
    counts = np.asarray(counts, dtype=np.int64)
    single = np.flatnonzero(counts == 1)
    if not single.size:
        return
    one = single.size == 1
    first = ", ".join(str(int(i)) for i in single[:5]) + (", ..." if single.size > 5 else "")
    warnings.append(f"{where}: {single.size} of {plural(counts.size, 'curve')} {'has' if one else 'have'} a single "
                    f"vertex (curve{'' if one else 's'} {first}: curveVertexCounts = 1): no segment to simulate; "
                    f"{'it stays a root' if one else 'each stays a root'} that follows the prim's transform (and is "
                    f"not drawn)")


def curve_spans(counts: np.ndarray, curve_type: str, basis: str, wrap: str) -> np.ndarray:
    """Number of spans (linear segments or cubic pieces) of each curve."""
    counts = np.asarray(counts, dtype=np.int64)
    if curve_type == "linear":
        return counts if wrap == "periodic" else np.maximum(counts - 1, 0)
    vstep = CUBIC_VSTEP[basis]
    if wrap == "periodic":
        return counts // vstep
    if wrap == "pinned" and basis != "bezier":
        return np.maximum(counts - 1, 0)
    return np.maximum((counts - 4) // vstep + 1, 0)


def varying_count(counts, curve_type: str, basis: str, wrap: str) -> int:
    """Values a ``varying`` (or ``faceVarying``) primvar needs: one per span end."""
    counts = np.asarray(counts, dtype=np.int64)
    if curve_type != "cubic":
        return int(counts.sum())
    spans = curve_spans(counts, curve_type, basis, wrap)
    return int((spans + (0 if wrap == "periodic" else 1)).sum())


def varying_per_vertex(values, counts, basis: str, wrap: str) -> np.ndarray:
    """A ``varying`` primvar of nonperiodic or pinned cubic curves (one value per span end) per
    control point: the span ends of a bezier curve are its control points 0, 3, 6, ... (the points
    between take the straight-line blend of the two ends by index); a nonperiodic bspline or
    catmullRom curve's span ends lie at its control points 1 .. n - 2 (the end points take the
    nearest end's value); a pinned one has a span end at every control point."""
    values = np.asarray(values, dtype=np.float64).reshape(-1)
    counts = np.asarray(counts, dtype=np.int64)
    out, at = [], 0
    for n in counts:
        n = int(n)
        if basis == "bezier":
            ends = (n - 1) // 3 + 1
            v = values[at:at + ends]
            out.append(np.interp(np.arange(n), 3 * np.arange(ends), v))
        elif wrap == "pinned":
            ends = n
            out.append(values[at:at + n])
        else:
            ends = n - 2
            v = values[at:at + ends]
            out.append(np.concatenate([v[:1], v, v[-1:]]))
        at += ends
    return np.concatenate(out) if out else np.zeros(0)


def primvar_count(interpolation: str, counts, num_points: int, curve_type: str, basis: str, wrap: str):
    """Values a primvar of ``interpolation`` needs on these curves (None: unknown interpolation)."""
    n_curves = int(np.asarray(counts).shape[0])
    if interpolation in ("varying", "faceVarying"):
        return varying_count(counts, curve_type, basis, wrap)
    return {"constant": 1, "uniform": n_curves, "vertex": int(num_points)}.get(interpolation)


def check_vertex_counts(counts, curve_type: str, basis: str, wrap: str, where: str) -> None:
    """UserError naming the first curve whose control point count its cubic basis cannot use."""
    if curve_type != "cubic":
        return
    counts = np.asarray(counts, dtype=np.int64)
    if wrap == "periodic":
        # a closed curve of n spans: 3n control points (bezier), n of them (bspline, catmullRom)
        step = 3 if basis == "bezier" else 1
        bad = (counts < 3) | (counts % step != 0)
        need = "3n (3, 6, 9, ...) control points" if basis == "bezier" else "at least 3 control points"
    elif basis == "bezier":
        bad = (counts < 4) | ((counts - 1) % 3 != 0)
        need = "3n + 1 (4, 7, 10, ...) control points"
    else:
        least = 2 if wrap == "pinned" else 4
        bad = counts < least
        need = f"at least {least} control points"
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise UserError(f"{where}: curveVertexCounts[{i}] = {int(counts[i])}: a {wrap} cubic {basis} curve needs {need}")


def check_primvar(values, interpolation: str, counts, num_points: int, curve_type: str, basis: str, wrap: str,
                  name: str, where: str, width: int = 1, nonnegative: bool = False, length: bool = False) -> np.ndarray:
    """``values`` reshaped to (K, width) after checking their count for ``interpolation``, that
    they are finite, (``nonnegative``, for widths) not negative and (``length``, for widths) not too
    large (:func:`~dftl_warp.checks.check_lengths`); UserError otherwise."""
    values = np.asarray(values, dtype=np.float64).reshape(-1, width)
    expected = primvar_count(interpolation, counts, num_points, curve_type, basis, wrap)
    if expected is None:
        raise UserError(f"{where}: {name}: unknown interpolation {interpolation!r}")
    if len(values) != expected:
        raise UserError(f"{where}: {name}: {len(values)} values for {interpolation!r} interpolation, expected {expected}")
    bad = ~np.isfinite(values).all(axis=1)
    if bad.any():
        raise UserError(f"{where}: {name}[{int(np.argmax(bad))}] is not finite")
    if nonnegative and (values < 0).any():
        raise UserError(f"{where}: {name}[{int(np.argmax((values < 0).any(axis=1)))}] is negative")
    if length:
        check_lengths(values, name, where)
    return values


def numbers(values, name: str, where: str, expected: str = "float[]") -> np.ndarray:
    """An authored value (a Vt array, or a scalar the renderer reads as one value) as a 1-D float
    array; UserError naming the attribute when it holds no numbers (``string[] widths``)."""
    arr = np.asarray(values)
    if arr.dtype.kind not in "iuf":
        shown = repr(str(values) if arr.ndim == 0 else [str(v) for v in arr.reshape(-1)[:3]])[:60]
        raise UserError(f"{where}: {name} = {shown}: expected numbers ({expected})")
    return arr.astype(np.float64).reshape(-1)


def colors(values, name: str, where: str) -> np.ndarray:
    """``displayColor`` values as (K, 3) floats: UserError naming the attribute when they are not
    numbers or not whole RGB triples (``float[] primvars:displayColor = [1, 0]``)."""
    arr = numbers(values, name, where, "color3f[]")
    if arr.size % 3:
        raise UserError(f"{where}: {name}: {arr.size} numbers are not RGB triples: expected color3f[]")
    return arr.reshape(-1, 3)


def whole_numbers(values, name: str, where: str) -> np.ndarray:
    """:func:`numbers` as int64, each a whole number (``float[] curveVertexCounts = [3.5, 4]`` is
    refused, not read as [3, 4])."""
    arr = numbers(values, name, where, "int[]")
    bad = np.flatnonzero(arr != np.round(arr))
    if bad.size:
        i = int(bad[0])
        raise UserError(f"{where}: {name}[{i}] = {arr[i]:g}: expected a whole number (int[])")
    return arr.astype(np.int64)


def vertex_counts(values, where: str) -> np.ndarray:
    """``curveVertexCounts`` as authored (None: none) as int64, for both readers: a scalar
    (``int curveVertexCounts = 7``, no brackets) is refused rather than read as one curve, and so
    are values that are not whole numbers (:func:`whole_numbers`)."""
    if values is None:
        return np.zeros(0, dtype=np.int64)
    if np.ndim(values) == 0:
        raise UserError(f"{where}: curveVertexCounts = {values}: one number, expected int[] (one count per curve, "
                        f"in brackets)")
    return whole_numbers(values, "curveVertexCounts", where)


def flattened(primvar, time, where: str):
    """The values of ``primvar`` at ``time``, expanded through its indices when it has them (USD's
    ``ComputeFlattened`` without its terminal warning): a UserError naming the first index out of
    range. None when it has no value."""
    values = primvar.Get(time)
    if values is None or not primvar.IsIndexed():
        return values
    indices = np.asarray(primvar.GetIndices(time), dtype=np.int64)
    n = len(values)
    bad = (indices < 0) | (indices >= n)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise UserError(f"{where}: {primvar.GetAttr().GetName()}:indices[{i}] = {int(indices[i])} is out of range "
                        f"({n} values)")
    return np.asarray(values)[indices]
