"""Write an imported groom as a USD stage the simulator reads (``dftl_warp`` USD reader):

- defaultPrim ``/Groom`` (Xform), ``/Groom/Hair`` (BasisCurves: linear, nonperiodic,
  curveVertexCounts, points, widths per vertex or constant, extent), and optionally
  ``/Groom/Head`` (Mesh with ``PhysicsCollisionAPI``, a collider for the simulation);
- metersPerUnit and upAxis of the input (points are written as read, not converted);
  startTimeCode 1, endTimeCode 48, timeCodesPerSecond 24.

The stage is built in memory, exported to a temporary file in the output's folder and renamed
into place, so an interrupted or failed import never leaves a half-written output.
"""

from __future__ import annotations

import os
import tempfile

import numpy as np

from ..durable import replace_file
from ..errors import UserError

OUTPUT_EXTENSIONS = (".usda", ".usdc", ".usd")
START, END, TCPS = 1, 48, 24


def check_output(path) -> str:
    path = os.fspath(path)
    if not path.strip():
        raise UserError(f"output {path!r}: empty path: give the stage to write ({', '.join(OUTPUT_EXTENSIONS)})")
    ext = os.path.splitext(path)[1].lower()
    if ext not in OUTPUT_EXTENSIONS:
        raise UserError(f"{path}: output must be a {', '.join(OUTPUT_EXTENSIONS)} file")
    folder = os.path.dirname(os.path.abspath(path))
    if not os.path.isdir(folder):
        what = "is a file, not a folder" if os.path.exists(folder) else "does not exist"
        raise UserError(f"{path}: folder {folder} {what}")
    if os.path.isdir(path):
        raise UserError(f"{path}: is a directory")
    return path


def build_stage(points, counts, widths, *, meters_per_unit: float, up_axis: str, head=None,
                source: str = "", friction: float | None = None):
    """An in-memory Usd.Stage holding the groom (and head collider)."""
    from pxr import Gf, Sdf, Usd, UsdGeom, UsdPhysics, Vt

    stage = Usd.Stage.CreateInMemory()
    UsdGeom.SetStageMetersPerUnit(stage, float(meters_per_unit))
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.z if up_axis == "Z" else UsdGeom.Tokens.y)
    stage.SetStartTimeCode(START)
    stage.SetEndTimeCode(END)
    stage.SetTimeCodesPerSecond(TCPS)
    if source:
        stage.GetRootLayer().documentation = f"Imported by dftl-warp import from {os.path.basename(source)}"
    root = UsdGeom.Xform.Define(stage, "/Groom")
    stage.SetDefaultPrim(root.GetPrim())

    curves = UsdGeom.BasisCurves.Define(stage, "/Groom/Hair")
    curves.CreateTypeAttr(UsdGeom.Tokens.linear)
    curves.CreateWrapAttr(UsdGeom.Tokens.nonperiodic)
    curves.CreateCurveVertexCountsAttr(Vt.IntArray.FromNumpy(np.asarray(counts, dtype=np.int32)))
    pts32 = np.ascontiguousarray(points, dtype=np.float32)
    curves.CreatePointsAttr(Vt.Vec3fArray.FromNumpy(pts32))
    widths = np.atleast_1d(np.asarray(widths, dtype=np.float32))
    curves.CreateWidthsAttr(Vt.FloatArray.FromNumpy(widths))
    curves.SetWidthsInterpolation(UsdGeom.Tokens.constant if widths.size == 1 else UsdGeom.Tokens.vertex)
    half = 0.5 * float(widths.max()) if widths.size else 0.0
    lo, hi = pts32.min(axis=0) - half, pts32.max(axis=0) + half
    curves.CreateExtentAttr(Vt.Vec3fArray([Gf.Vec3f(*map(float, lo)), Gf.Vec3f(*map(float, hi))]))

    if head is not None:
        mesh = UsdGeom.Mesh.Define(stage, "/Groom/Head")
        hp = np.ascontiguousarray(head.points, dtype=np.float32)
        mesh.CreatePointsAttr(Vt.Vec3fArray.FromNumpy(hp))
        mesh.CreateFaceVertexCountsAttr(Vt.IntArray.FromNumpy(head.face_counts.astype(np.int32)))
        mesh.CreateFaceVertexIndicesAttr(Vt.IntArray.FromNumpy(head.face_indices.astype(np.int32)))
        mesh.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)
        mesh.CreateExtentAttr(Vt.Vec3fArray([Gf.Vec3f(*map(float, hp.min(axis=0))),
                                              Gf.Vec3f(*map(float, hp.max(axis=0)))]))
        UsdPhysics.CollisionAPI.Apply(mesh.GetPrim())
        if friction is not None:
            mesh.GetPrim().CreateAttribute("dftl:friction", Sdf.ValueTypeNames.Float, custom=True).Set(float(friction))
    return stage


def write_stage(stage, path) -> None:
    """Export ``stage``'s root layer to ``path`` atomically (temporary file + rename)."""
    path = check_output(path)
    folder = os.path.dirname(os.path.abspath(path))
    ext = os.path.splitext(path)[1]
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{os.path.basename(path)}.", suffix=ext, dir=folder)
        os.close(fd)
    except OSError as exc:
        raise UserError(f"{path}: cannot write: {exc.strerror or exc}") from None
    try:
        if ext.lower() == ".usd":
            ok = stage.GetRootLayer().Export(tmp, args={"format": "usdc"})
        else:
            ok = stage.GetRootLayer().Export(tmp)
        if not ok:
            raise UserError(f"{path}: USD could not write the stage")
        replace_file(tmp, path, permissions=True)  # on the disk, then renamed (mkstemp's 0600 made usual)
    except OSError as exc:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise UserError(f"{path}: cannot write: {exc.strerror or exc}") from None
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise
