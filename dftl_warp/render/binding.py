"""Render curves of a guide binding cache (``simulate --guides-output binding``, docs/guides.md),
deformed at the time rendered as ``--guides-output curves`` would have written them.

Such a cache holds the simulated guides (time samples) and, on each render BasisCurves prim, its
rest points (as authored), ``rel dftl:guides`` and the binding as primvars: ``dftl:guideIds`` and
``dftl:guideWeights`` (uniform, elementSize k), ``dftl:guideOffsets`` (vertex; offsets in the blended
guide frame) and ``dftl:guideParam`` (vertex; arc length from the root). The binding was computed in
world space at the simulation's first frame, the guides' first time sample: the guides' rest shape
there gives back what the cache leaves out (their arc lengths and reference points,
:func:`~dftl_warp.guides.binding.reference_points`). Each frame the guides in world space deform the
render points (:func:`~dftl_warp.guides.binding.deform_reference`, float64), which go back to the
render prim's local space with their roots where its transform holds them
(:func:`~dftl_warp.guides.binding.pin_roots`; not for roots bound to a ``dftl:rootMesh``), as
:class:`~dftl_warp.guides.scene.GuideSet` does when it writes curves.
"""

from __future__ import annotations

import numpy as np

from ..errors import UserError
from ..guides.binding import MAX_K, Binding, check_strands, deform_reference, pin_roots, reference_points
from ..guides.frames import arc_fractions
from ..usd import curves as curve_checks
from ..usd.guides import read_guide_paths
from ..usd.scene import transform_points

#: the primvar that marks a render prim bound to guides
IDS = "dftl:guideIds"


def is_bound(prim) -> bool:
    from pxr import UsdGeom

    return UsdGeom.PrimvarsAPI(prim).HasPrimvar(IDS)


def _values(prim, name: str, where: str, count: int, width: int = 1) -> np.ndarray:
    from pxr import UsdGeom

    pv = UsdGeom.PrimvarsAPI(prim).GetPrimvar(name)
    value = pv.Get() if pv else None
    if value is None:
        raise UserError(f"{where}: a guide binding without primvars:{name}: cannot deform its curves (write it with "
                        "simulate --guides-output binding)")
    v = curve_checks.numbers(value, f"primvars:{name}", where)
    if v.size % width:
        raise UserError(f"{where}: primvars:{name} has {v.size} numbers: expected {count} values of {width}")
    v = v.reshape(-1, width) if width > 1 else v
    if len(v) != count or not np.isfinite(v).all():
        raise UserError(f"{where}: primvars:{name} has {len(v)} {'finite ' if len(v) == count else ''}values, "
                        f"expected {count} finite ones")
    return v


def _guides(stage, paths, time, source):
    """(world points, counts) of the guide prims at ``time``, concatenated in ``paths`` order."""
    from pxr import UsdGeom

    pts, counts = [], []
    for path in paths:
        prim = stage.GetPrimAtPath(path)
        g = UsdGeom.BasisCurves(prim)
        p = np.asarray(g.GetPointsAttr().Get(time) or [], dtype=np.float64).reshape(-1, 3)
        m = np.array(UsdGeom.Xformable(prim).ComputeLocalToWorldTransform(time), dtype=np.float64)
        pts.append(transform_points(m, p))
        counts.append(curve_checks.vertex_counts(g.GetCurveVertexCountsAttr().Get(time), f"{source}: {path}"))
    return np.concatenate(pts), np.concatenate(counts)


def rest_time(stage, paths):
    """The binding's frame: the guides' first time sample (their default time when they have none)."""
    from pxr import Usd, UsdGeom

    first = []
    for path in paths:
        samples = UsdGeom.BasisCurves(stage.GetPrimAtPath(path)).GetPointsAttr().GetTimeSamples()
        if samples:
            first.append(samples[0])
    return Usd.TimeCode(min(first)) if first else Usd.TimeCode.Default()


def read_binding(prim, counts: np.ndarray, source: str):
    """(Binding, guide prim paths) of the render prim ``prim`` whose curves have ``counts`` vertices;
    UserError naming the file, the prim and what does not fit."""
    from pxr import UsdGeom

    where = f"{source}: {prim.GetPath()}"
    paths = read_guide_paths(prim, source)
    if not paths:
        raise UserError(f"{where}: primvars:{IDS} without rel dftl:guides: a guide binding must name its guide prims")
    stage = prim.GetStage()
    gp, gc = _guides(stage, paths, rest_time(stage, paths), source)
    try:
        gp, gc, gs = check_strands(gp, gc, "guide points", "guide curveVertexCounts")
    except ValueError as exc:
        raise UserError(f"{where}: its guides {', '.join(paths)}: {exc}") from None
    R, Vr = len(counts), int(counts.sum())
    k = UsdGeom.PrimvarsAPI(prim).GetPrimvar(IDS).GetElementSize()
    if not 1 <= k <= MAX_K:
        raise UserError(f"{where}: primvars:{IDS} has elementSize {k}: expected 1..{MAX_K} guides per curve")
    ids = _values(prim, IDS, where, R * k).reshape(R, k)
    weights = _values(prim, "dftl:guideWeights", where, R * k).reshape(R, k)
    # -1: no guide in that slot (weight 0), as bind writes for a render strand that is a guide
    bad = np.flatnonzero(((ids < 0) & ((ids != -1) | (weights != 0))) | (ids >= len(gc)) | (ids != np.round(ids))
                         | (ids[:, :1] < 0).repeat(k, axis=1))
    if bad.size:
        raise UserError(f"{where}: primvars:{IDS}[{bad[0]}] = {ids.reshape(-1)[bad[0]]:g}: not a guide index in "
                        f"0..{len(gc) - 1} ({len(gc)} curves in {', '.join(paths)})")
    offsets = _values(prim, "dftl:guideOffsets", where, Vr, 3)
    t = _values(prim, "dftl:guideParam", where, Vr)
    full_ids = np.full((R, MAX_K), -1, dtype=np.int64)
    full_w = np.zeros((R, MAX_K))
    full_ids[:, :k], full_w[:, :k] = ids.astype(np.int64), weights
    # a render strand that is a guide: all the weight on one guide, no offset (bind's convention)
    starts = np.concatenate([[0], np.cumsum(counts)[:-1]]).astype(np.int64)
    still = np.bincount(np.repeat(np.arange(R), counts), weights=np.abs(offsets).sum(axis=1), minlength=R) == 0
    render_guide = np.where((full_w[:, 0] == 1.0) & still & (counts == gc[full_ids[:, 0]]), full_ids[:, 0], -1)
    ref_guide, ref_vertex = reference_points(gp, gs, gc)
    binding = Binding(k=k, weights_kind="gaussian", frames="blend", clump=0.0, clump_shape=1.0,
                      guide_starts=gs, guide_counts=gc, guide_frac=arc_fractions(gp, gs, gc, normalise=False),
                      ref_guide=ref_guide, ref_vertex=ref_vertex, render_starts=starts, render_counts=counts,
                      guide_ids=full_ids, weights=full_w, t=t, offsets=offsets, render_guide=render_guide)
    return binding, paths


def deformed_points(prim, points: np.ndarray, counts: np.ndarray, time, source: str) -> np.ndarray:
    """The render prim's local ``points`` (its rest curves, as authored) deformed by its guides at
    ``time``, in its local space (float64). At the default time (no frame) they stay at rest."""
    from pxr import UsdGeom

    binding, paths = read_binding(prim, counts, source)
    if time.IsDefault():
        return points
    gp, gc = _guides(prim.GetStage(), paths, time, source)
    if not np.array_equal(gc, binding.guide_counts):
        raise UserError(f"{source}: {prim.GetPath()}: its guides {', '.join(paths)} change their curveVertexCounts "
                        "after the binding's frame")
    world = deform_reference(binding, gp)
    m = np.array(UsdGeom.Xformable(prim).ComputeLocalToWorldTransform(time), dtype=np.float64)
    local = transform_points(np.linalg.inv(m), world)
    if not prim.GetRelationship("dftl:rootMesh"):   # roots on a root mesh follow the guides (simulate warns)
        local = pin_roots(local, binding, points[binding.render_starts])
    return local
