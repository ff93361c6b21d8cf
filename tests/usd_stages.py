"""Small USD stages for the USD tests (not a test module)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from pxr import Gf, Sdf, Usd, UsdGeom, Vt


#: the layer metadata of a hand-written test stage: frames 1..3, Y up, metres
USDA_HEAD = '#usda 1.0\n(\n    startTimeCode = 1\n    endTimeCode = 3\n    upAxis = "Y"\n    metersPerUnit = 1\n)\n'


def new_stage(path, *, up="Y", meters_per_unit=1.0, start=1, end=10, fps=24.0, default_prim=True):
    """A stage with /World; ``None`` leaves a metadata field unauthored."""
    path = Path(path)
    stage = Usd.Stage.CreateNew(str(path))
    if up is not None:
        UsdGeom.SetStageUpAxis(stage, up)
    if meters_per_unit is not None:
        UsdGeom.SetStageMetersPerUnit(stage, meters_per_unit)
    if fps is not None:
        stage.SetTimeCodesPerSecond(fps)
    if start is not None:
        stage.SetStartTimeCode(start)
    if end is not None:
        stage.SetEndTimeCode(end)
    world = UsdGeom.Xform.Define(stage, "/World")
    if default_prim:
        stage.SetDefaultPrim(world.GetPrim())
    return stage


def add_curves(stage, path, points, counts, *, curve_type="linear", basis=None, wrap=None, widths=None,
               bending=False):
    """A BasisCurves prim; points/counts are authored as given (no checks).

    With ``widths`` the prim also authors ``dftl:bending = false`` unless ``bending`` is true (or
    None: unauthored): most tests give widths for the colliders' contact distance and test the DFTL
    chain, which a prim with widths is only when it says so (it bends as an elastic rod by default)."""
    curves = UsdGeom.BasisCurves.Define(stage, path)
    curves.CreateTypeAttr(curve_type)
    if basis is not None:
        curves.CreateBasisAttr(basis)
    if wrap is not None:
        curves.CreateWrapAttr(wrap)
    curves.CreateCurveVertexCountsAttr(Vt.IntArray([int(c) for c in counts]))
    pts = np.asarray(points, dtype=np.float32).reshape(-1, 3)
    curves.CreatePointsAttr(Vt.Vec3fArray.FromNumpy(np.ascontiguousarray(pts)))
    if widths is not None:
        curves.CreateWidthsAttr(Vt.FloatArray([float(w) for w in np.atleast_1d(widths)]))
        curves.SetWidthsInterpolation("constant" if np.size(widths) == 1 else "vertex")
        if bending is not None and not bending:
            curves.GetPrim().CreateAttribute("dftl:bending", Sdf.ValueTypeNames.Bool, custom=True).Set(False)
    return curves


def chain(n, spacing=1.0, direction=(1.0, 0.0, 0.0), origin=(0.0, 0.0, 0.0)):
    d = np.asarray(direction, dtype=np.float64)
    return np.asarray(origin, dtype=np.float64) + np.arange(n)[:, None] * spacing * d


def set_attr(prim, name, type_name, value):
    prim.CreateAttribute(name, getattr(Sdf.ValueTypeNames, type_name), custom=True).Set(value)


def animated_xform(stage, path, *, translate=None, rotate_y=None):
    """An Xform with time-sampled ops: ``translate`` / ``rotate_y`` map frame -> value."""
    xf = UsdGeom.Xform.Define(stage, path)
    if translate:
        op = xf.AddTranslateOp()
        for frame, value in translate.items():
            op.Set(Gf.Vec3d(*value), frame)
    if rotate_y:
        op = xf.AddRotateYOp()
        for frame, value in rotate_y.items():
            op.Set(float(value), frame)
    return xf


def composed_samples(path, prim_path, attr="points"):
    """{time: (N, 3) array} of a composed attribute's time samples."""
    stage = Usd.Stage.Open(str(path))
    a = stage.GetPrimAtPath(prim_path).GetAttribute(attr)
    return {t: np.array(a.Get(t), dtype=np.float64) for t in a.GetTimeSamples()}


def local_to_world(path, prim_path, time):
    stage = Usd.Stage.Open(str(path))
    m = UsdGeom.Imageable(stage.GetPrimAtPath(prim_path)).ComputeLocalToWorldTransform(time)
    return np.array(m, dtype=np.float64)
