"""``dftl-warp diff A B``: how far two caches' points are apart, per frame and prim (docs/caches.md).

For every BasisCurves prim the two stages share and every time code both sample: the max and RMS
distance between corresponding points (stage units, the prims' local space) and the same
relative to the length of the point's strand (in A at that frame). The first frame whose max
difference exceeds ``--tolerance`` (stage units; ``--relative``: a share of the strand length) is
named. A prim's default-time points are compared only when neither file samples it in time; when
one does and they share no time code that is bad input, and frames sampled in only one file are
left out with one warning, as are prims held by one file only. Exit status 0 when every frame is
within tolerance, 1 otherwise, 2 for bad input (missing or unreadable file, no shared prims or
frames, different point or curve vertex counts: one line naming the files).
"""

from __future__ import annotations

import math
import os
import sys

from . import strict_json


def add_parser(sub):
    from ..output.paths import path_argument

    p = sub.add_parser(
        "diff",
        help="compare two caches per frame and prim: max and RMS point difference; exit 1 beyond --tolerance",
        description="Compare the time-sampled points of the BasisCurves prims of A and B, frame by frame, at the "
                    "frames both sample (none in common: bad input; frames in one file only: a warning). "
                    "Exit status 0 when within --tolerance, 1 otherwise, 2 for bad input.",
    )
    p.add_argument("a", metavar="A", type=path_argument("the USD stage A"),
                   help="USD stage (a dftl-warp output or any stage with BasisCurves)")
    p.add_argument("b", metavar="B", type=path_argument("the USD stage B"), help="USD stage to compare with A")
    p.add_argument("--tolerance", type=float, default=0.0, metavar="T",
                   help="largest point difference allowed (stage units; default 0: bitwise equal points)")
    p.add_argument("--relative", action="store_true",
                   help="--tolerance is a share of the strand length, not stage units")
    p.add_argument("--json", action="store_true", help="print the comparison as JSON")
    p.set_defaults(run=run)


def _open(path):
    from pxr import Tf, Usd, UsdGeom

    from ..errors import UserError
    from ..usd.stage import open_failure

    if not os.path.exists(path):
        raise UserError(f"{path}: no such file")
    if os.path.isdir(path):
        raise UserError(f"{path}: is a folder, not a USD file")
    try:
        stage = Usd.Stage.Open(str(path))
    except Tf.ErrorException as exc:   # the reason, as simulate gives it (a parse error, bytes not UTF-8)
        raise open_failure(str(path), exc) from None
    if stage is None:
        raise UserError(f"{path}: cannot open as a USD stage")
    return stage, {str(p.GetPath()): UsdGeom.BasisCurves(p) for p in stage.Traverse() if p.IsA(UsdGeom.BasisCurves)}


def _strand_lengths(points, counts):
    import numpy as np

    seg = np.linalg.norm(np.diff(points, axis=0), axis=1)
    starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
    keep = np.ones(len(seg), dtype=bool)
    keep[(starts[1:] - 1)] = False  # segments across strands
    cums = np.concatenate([[0.0], np.cumsum(np.where(keep, seg, 0.0))])
    ends = starts + counts - 1
    return cums[ends] - cums[starts]


def frames_text(times) -> str:
    """``times`` (sorted) as text: runs of whole-frame steps as ``1..10``, the rest listed."""
    if not times:
        return "no time samples"
    runs = []
    for t in times:
        if runs and t - runs[-1][1] == 1.0:
            runs[-1][1] = t
        else:
            runs.append([t, t])
    parts = [f"{a:g}" if a == b else f"{a:g}..{b:g}" for a, b in runs]
    if len(parts) > 6:
        parts = [*parts[:3], "...", *parts[-2:]]
    return ("frame " if len(times) == 1 else "frames ") + ", ".join(parts)


def _common_times(path, a_path, b_path, ta, tb, only_a, only_b):
    """The time codes to compare for prim ``path`` (``[None]``: its default-time points, when
    neither file samples it); records the frames sampled in only one file."""
    from ..errors import UserError

    if not ta and not tb:
        return [None]
    common = sorted(set(ta) & set(tb))
    if not common:
        raise UserError(f"{a_path} ({frames_text(ta)}) and {b_path} ({frames_text(tb)}) share no frame "
                        f"of {path}: nothing to compare")
    only_a.update(set(ta) - set(tb))
    only_b.update(set(tb) - set(ta))
    return common


def _check_curves(path, a_path, b_path, counts, other) -> None:
    """Equal points split into other curves are another groom: bad input naming the first curve
    whose vertex count differs (or the curve counts)."""
    import numpy as np

    from ..errors import UserError

    other = np.asarray(other if other is not None else [], dtype=np.int64)
    if np.array_equal(counts, other):
        return
    if counts.shape != other.shape:
        raise UserError(f"{path}: {counts.size} curves in {a_path}, {other.size} in {b_path} (curveVertexCounts)")
    i = int(np.flatnonzero(counts != other)[0])
    raise UserError(f"{path}: curve {i} has {counts[i]} vertices in {a_path}, {other[i]} in {b_path} "
                    "(curveVertexCounts differ)")


def compare(a_path, b_path) -> dict:
    """Per prim and frame: ``max``, ``rms`` (stage units) and ``max_relative``, ``rms_relative``
    (per point, divided by its strand's length in A). ``frames_only_in_a``/``_b``: frames sampled
    in one file only (not compared; :func:`frames_warning`). ``not_finite``: per file and prim, the
    first point that is not finite (its distances are NaN, beyond any tolerance)."""
    import numpy as np
    from pxr import Usd

    from ..errors import UserError

    (stage_a, a), (stage_b, b) = _open(a_path), _open(b_path)  # the stages stay open while compared
    shared = [p for p in a if p in b]
    if not shared:
        raise UserError(f"{a_path}, {b_path}: no BasisCurves prim in common")
    prims, only_a, only_b, not_finite = {}, set(), set(), {}
    for path in shared:
        pa, pb = a[path].GetPointsAttr(), b[path].GetPointsAttr()
        counts = np.asarray(a[path].GetCurveVertexCountsAttr().Get(), dtype=np.int64)
        times = _common_times(path, a_path, b_path, pa.GetTimeSamples(), pb.GetTimeSamples(), only_a, only_b)
        rows = []
        for t in times:
            code = Usd.TimeCode.Default() if t is None else Usd.TimeCode(t)
            when = "at the default time (no time samples)" if t is None else f"at frame {t:g}"
            va, vb = pa.Get(code), pb.Get(code)
            for value, file in ((va, a_path), (vb, b_path)):
                if value is None:
                    raise UserError(f"{file}: {path} has no points {when}")
            xa = np.asarray(va, dtype=np.float64).reshape(-1, 3)
            xb = np.asarray(vb, dtype=np.float64).reshape(-1, 3)
            for x, file in ((xa, a_path), (xb, b_path)):   # named once per file and prim: compared as NaN
                bad = np.flatnonzero(~np.isfinite(x).all(axis=1))
                if bad.size and (file, path) not in not_finite:
                    not_finite[(file, path)] = f"{file}: {path}: points[{bad[0]}] {when} is not finite" + (
                        f" ({bad.size} points)" if bad.size > 1 else "")
            if xa.shape != xb.shape:
                raise UserError(f"{path}: {xa.shape[0]} points in {a_path}, {xb.shape[0]} in {b_path} {when}")
            if not rows:   # as many points: in the same curves?
                _check_curves(path, a_path, b_path, counts, b[path].GetCurveVertexCountsAttr().Get())
            d = np.linalg.norm(xa - xb, axis=1) if xa.size else np.zeros(0)
            lengths = np.repeat(_strand_lengths(xa, counts), counts) if counts.sum() == len(xa) and len(xa) else \
                np.ones(len(xa))
            rel = d / np.where(lengths > 0, lengths, 1.0)
            nan = not (np.isfinite(d).all())
            rows.append({"time": t, "max": float("nan") if nan else float(d.max(initial=0.0)),
                         "rms": float(math.sqrt(np.mean(d * d))) if d.size else 0.0,
                         "max_relative": float("nan") if nan else float(rel.max(initial=0.0)),
                         "rms_relative": float(math.sqrt(np.mean(rel * rel))) if rel.size else 0.0})
        prims[path] = rows
    return {"a": str(a_path), "b": str(b_path), "prims": prims,
            "only_in_a": [p for p in a if p not in b], "only_in_b": [p for p in b if p not in a],
            "frames_only_in_a": sorted(only_a), "frames_only_in_b": sorted(only_b),
            "not_finite": list(not_finite.values())}


def frames_warning(result: dict) -> str | None:
    """One line naming the frames sampled, and the prims held, in only one file (left out of the
    comparison), or None."""
    parts = [f"{frames_text(result[f'frames_only_in_{x}'])} only in {result[x]}"
             for x in ("a", "b") if result[f"frames_only_in_{x}"]]
    parts += [f"{_prims_text(result[f'only_in_{x}'])} only in {result[x]}"
              for x in ("a", "b") if result[f"only_in_{x}"]]
    return f"{'; '.join(parts)}: not compared" if parts else None


def _prims_text(paths: list) -> str:
    """``paths`` as text: the first three named, then how many more."""
    more = f" and {len(paths) - 3} more" if len(paths) > 3 else ""
    return ("prim " if len(paths) == 1 else "prims ") + ", ".join(paths[:3]) + more


def first_beyond(result: dict, tolerance: float, relative: bool = False):
    """(time, prim, value) of the earliest frame whose max difference exceeds ``tolerance``, or None
    (time None: the default-time points)."""
    key = "max_relative" if relative else "max"
    worst = None
    for path, rows in result["prims"].items():
        for r in rows:
            v = r[key]
            if not v <= tolerance:
                t = -math.inf if r["time"] is None else r["time"]
                if worst is None or t < worst[0]:
                    worst = (t, path, v)
                break
    if worst is not None and worst[0] == -math.inf:
        worst = (None, *worst[1:])
    return worst


def run(args) -> int:
    from ..errors import UserError

    if not math.isfinite(args.tolerance) or args.tolerance < 0:
        raise UserError(f"--tolerance must be a finite number >= 0, got {args.tolerance}")
    result = compare(args.a, args.b)
    for warning in (frames_warning(result), *result["not_finite"]):
        if warning:
            print(f"dftl-warp: warning: {warning}", file=sys.stderr)
    beyond = first_beyond(result, args.tolerance, args.relative)
    result["tolerance"] = args.tolerance
    result["relative"] = args.relative
    result["first_beyond"] = None if beyond is None else {"time": beyond[0], "prim": beyond[1], "value": beyond[2]}
    result["within_tolerance"] = beyond is None
    if args.json:   # strict JSON: a distance that is not finite (NaN points) is null
        print(strict_json.dumps(result, indent=1))
    else:
        print(f"{'frame':>8} {'prim':<32} {'max':>12} {'rms':>12} {'max/length':>12} {'rms/length':>12}")
        for path, rows in result["prims"].items():
            for r in rows:
                t = "-" if r["time"] is None else f"{r['time']:g}"
                print(f"{t:>8} {path:<32} {r['max']:>12.4g} {r['rms']:>12.4g} {r['max_relative']:>12.4g} "
                      f"{r['rms_relative']:>12.4g}")
        unit = "of the strand length" if args.relative else "stage units"
        if beyond is None:
            print(f"within tolerance {args.tolerance:g} {unit}")
        else:
            when = "the default time" if beyond[0] is None else f"frame {beyond[0]:g}"
            print(f"first difference beyond {args.tolerance:g} {unit}: {when}, {beyond[1]} "
                  f"({beyond[2]:.4g})", file=sys.stdout)
    return 0 if beyond is None else 1
