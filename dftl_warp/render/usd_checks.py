"""Checks of the values the renderer reads from USD prims, and its notes about what it leaves out.

- :func:`number`: a schema attribute the renderer reads as one number (a Sphere's ``radius``, a
  Cube's ``size``, a Camera's ``focalLength``): a string, a bool or an array of the wrong type is a
  :class:`~dftl_warp.errors.UserError` naming file, prim, attribute and value, not a traceback;
- :func:`capsule_axis`: a Capsule's ``axis`` token (X, Y or Z);
- :func:`mesh_faces`: a Mesh's points and triangles: faces of fewer than 3 vertices and
  ``holeIndices`` out of range are refused as the simulation's reader refuses them
  (:mod:`dftl_warp.usd.colliders`), hole faces are not drawn;
- :func:`skipped_note` and :func:`widthless_note`: one warning line each for the prims the renderer
  does not draw (NurbsCurves, Cylinder, Cone, ...) and for the BasisCurves it draws at a default width.
"""

from __future__ import annotations

import numpy as np

from ..errors import UserError
from ..usd import curves as curve_checks
from ..usd.colliders import fan_triangulate, remove_holes
from ..usd import values
from ..usd.values import shown

#: the prim types the renderer draws (UsdGeom type names)
DRAWN_TYPES = ("BasisCurves", "Sphere", "Capsule", "Cube", "Mesh")

#: how many prim paths a note lists before "..."
LISTED = 3


def number(value, name: str, where: str, default: float | None = None) -> float:
    """``value`` of attribute ``name`` as a float (``default`` when it is None and a default is
    given); a string, a bool, an array or a vector is a UserError naming ``where`` and the value, in
    the simulation reader's words (:func:`dftl_warp.usd.values.number`; ``string radius = "big"``
    crashed the renderer with "could not convert string to float")."""
    if value is None and default is not None:
        return float(default)
    return values.number(value, name, where)


def capsule_axis(value, where: str) -> int:
    """The index (0, 1, 2) of a Capsule's ``axis`` token; UserError for any other value, as the
    simulation's reader refuses it (``"W"`` crashed the renderer)."""
    axis = "Z" if value is None else value   # USD's fallback
    if not isinstance(axis, str) or axis not in ("X", "Y", "Z"):
        raise UserError(f"{where}: axis = {shown(axis)}: must be \"X\", \"Y\" or \"Z\" "
                        "(UsdGeomCapsule's axis tokens)")
    return "XYZ".index(axis)


def mesh_faces(points, counts, indices, holes, where: str):
    """(points (N, 3), triangles (T, 3)) of a Mesh's authored arrays: every face of 3 or more
    vertices fan-triangulated, the faces listed in ``holeIndices`` left out. A face of fewer than 3
    vertices or a hole index out of range is a UserError in the words of the simulation's reader (the
    renderer dropped such faces, and drew hole faces, without a word); so are values that are not
    numbers, non-finite points and face vertex indices out of range."""
    pts = curve_checks.numbers(points, "points", where, "point3f[]")
    if pts.size % 3:
        raise UserError(f"{where}: points: {pts.size} numbers are not xyz triples: expected point3f[]")
    pts = pts.reshape(-1, 3)
    fvc = curve_checks.whole_numbers(counts, "faceVertexCounts", where)
    fvi = curve_checks.whole_numbers(indices, "faceVertexIndices", where)
    bad = ~np.isfinite(pts).all(axis=1)
    if bad.any():
        raise UserError(f"{where}: points[{int(np.argmax(bad))}] is not finite")
    small = np.flatnonzero(fvc < 3)
    if small.size:
        i = int(small[0])
        raise UserError(f"{where}: faceVertexCounts[{i}] = {int(fvc[i])}: a face needs at least 3 vertices")
    if fvc.sum() != len(fvi):
        raise UserError(f"{where}: faceVertexIndices has {len(fvi)} entries but faceVertexCounts sums to "
                        f"{int(fvc.sum())}")
    bad = (fvi < 0) | (fvi >= len(pts))
    if bad.any():
        i = int(np.argmax(bad))
        raise UserError(f"{where}: faceVertexIndices[{i}] = {int(fvi[i])} is not a point index (0..{len(pts) - 1})")
    if holes is not None and np.size(holes):   # the simulation reader's rule and words
        fvc, fvi = remove_holes(fvc, fvi, curve_checks.whole_numbers(holes, "holeIndices", where), where)
    return pts, fan_triangulate(fvc, fvi)


def listed(paths, noun: str) -> str:
    """``2 Cylinder prims (/W/A, /W/B)``: a count, ``noun`` and the first :data:`LISTED` paths."""
    more = " ..." if len(paths) > LISTED else ""
    return f"{len(paths)} {noun}{'s' if len(paths) > 1 else ''} ({', '.join(paths[:LISTED])}{more})"


def skipped_note(source: str, skipped: dict) -> str | None:
    """One warning for the drawn-looking prims the renderer skips (``skipped``: type name -> prim
    paths), or None: ``FILE: 1 NurbsCurves prim (/W/N); 2 Cylinder prims (/W/A, /W/B): not drawn
    (...)``, as the simulation's reader says of the curves it does not simulate."""
    if not skipped:
        return None
    kinds = "; ".join(listed(paths, f"{kind} prim") for kind, paths in skipped.items())
    return f"{source}: {kinds}: not drawn (only {', '.join(DRAWN_TYPES[:-1])} and {DRAWN_TYPES[-1]} prims are); skipped"


def widthless_note(source: str, paths: list) -> str | None:
    """One warning for the BasisCurves prims drawn at the default width (no ``widths`` or
    ``primvars:widths``), or None."""
    if not paths:
        return None
    whose = "each prim's" if len(paths) > 1 else "its"
    return (f"{source}: {listed(paths, 'BasisCurves prim')} without widths or primvars:widths: drawn at a default "
            f"width, 1/1000 of {whose} bounding-box diagonal")
