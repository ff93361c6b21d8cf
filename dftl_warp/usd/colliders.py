"""Collider prims (``UsdPhysics.CollisionAPI``) and the mesh a groom's roots are bound to
(``dftl:rootMesh``), read into plain :mod:`~dftl_warp.usd.scene` data.

Sphere, Capsule, Cube and Mesh prims are read and checked here (kinds "sphere", "capsule", "box",
"mesh": :data:`BUILTIN_KINDS`). A collision prim of any other type whose type name was accepted
(:func:`accept_collider_type`; the collider shapes of :mod:`dftl_warp.features.colliders` accept
their ``usd_kind`` when they are registered) is read generically: ``kind`` is its type name and
``attributes`` its own attributes' values (plain Python and numpy), for the shape's ``from_prim``
to map. Collision prims of other types are ignored with a warning. Mesh colliders honour ``holeIndices``
(those faces are removed) and ``orientation`` (a ``leftHanded`` mesh's faces are reversed, so
that the triangles always wind counter-clockwise seen from outside).

Bad data raises :class:`~dftl_warp.errors.UserError` naming the file, the prim and the index.
"""

from __future__ import annotations

import numpy as np

from ..errors import UserError, plural
from .attributes import read_values
from ..checks import check_lengths
from .material import bound_material
from .sampling import TransformReader, points_sampler, scale_growth
from .scene import ColliderPrim, MeshSource
from .values import at_text, boolean, number, shown


#: the ColliderPrim kinds this module reads itself
BUILTIN_KINDS = ("sphere", "capsule", "box", "mesh")

#: prim type names (``"Cylinder"``) of collision prims read generically
GENERIC_TYPES: set[str] = set()


def accept_collider_type(type_name: str) -> None:
    """Read collision prims of type ``type_name`` generically (kind = the type name)."""
    if type_name not in BUILTIN_KINDS:
        GENERIC_TYPES.add(type_name)


def _plain(value):
    """A USD attribute value as plain data: bool, int, float, str, or a numpy array."""
    if isinstance(value, (bool, int, float, str)):
        return value
    try:
        array = np.array(value)
    except (TypeError, ValueError):
        return str(value)
    if array.dtype.kind in "iuf":
        return array.astype(np.int64 if array.dtype.kind in "iu" else np.float64)
    return array if array.dtype != object else str(value)


def generic_attributes(prim, code) -> dict:
    """The values at ``code`` of ``prim``'s own attributes (names without a namespace: not
    ``xformOp:*``, ``physics:*``, ``dftl:*``), as plain data."""
    out = {}
    for attr in prim.GetAttributes():
        name = attr.GetName()
        if ":" in name:
            continue
        value = attr.Get(code)
        if value is not None:
            out[name] = _plain(value)
    return out


def _code(time):
    from pxr import Usd

    return Usd.TimeCode.Default() if time is None else Usd.TimeCode(float(time))


def first_bad_row(array: np.ndarray) -> int | None:
    """Index of the first row of ``array`` (N, 3) with a non-finite entry, or None."""
    bad = ~np.isfinite(array).all(axis=1)
    return int(np.flatnonzero(bad)[0]) if bad.any() else None


def fmt_point(p) -> str:
    return "(" + ", ".join(f"{float(v):g}" for v in p) + ")"


def fan_triangulate(counts: np.ndarray, indices: np.ndarray) -> np.ndarray:
    """Triangles (T, 3) of polygon faces split as fans around their first vertex."""
    starts = np.zeros(counts.size, dtype=np.int64)
    np.cumsum(counts[:-1], out=starts[1:])
    ntri = counts - 2
    face = np.repeat(np.arange(counts.size), ntri)
    k = np.arange(int(ntri.sum())) - np.repeat(np.cumsum(ntri) - ntri, ntri)
    first = starts[face]
    return np.stack([indices[first], indices[first + k + 1], indices[first + k + 2]], axis=1)


def remove_holes(fvc: np.ndarray, fvi: np.ndarray, holes, where: str):
    """``(faceVertexCounts, faceVertexIndices)`` without the faces listed in ``holes``
    (``holeIndices``: face indices); an index out of range is an error."""
    holes = np.asarray(holes if holes is not None else [], dtype=np.int64).reshape(-1)
    if holes.size == 0:
        return fvc, fvi
    bad = np.flatnonzero((holes < 0) | (holes >= fvc.size))
    if bad.size:
        i = int(bad[0])
        raise UserError(f"{where}: holeIndices[{i}] = {int(holes[i])} is out of range (0..{fvc.size - 1})")
    keep = np.ones(fvc.size, dtype=bool)
    keep[holes] = False
    if not keep.any():
        raise UserError(f"{where}: holeIndices remove every face of the mesh")
    return fvc[keep], fvi[np.repeat(keep, fvc)]


def mesh_triangles(mesh, code, where: str, faces: bool = False):
    """(points, triangles) of a Mesh as authored: faces listed in ``holeIndices`` removed, the rest
    fan-triangulated, and wound counter-clockwise seen from the side the mesh's normals point to
    (``orientation = "leftHanded"`` faces are reversed, so the inside stays inside). With
    ``faces``, also the authored face index of each triangle (T,) and the number of faces kept."""
    pts, fvc, fvi = _mesh_arrays(mesh, code, where)
    holes = mesh.GetHoleIndicesAttr().Get(code)
    kept = np.ones(fvc.size, dtype=bool)
    kept_fvc, fvi = remove_holes(fvc, fvi, holes, where)
    if kept_fvc.size != fvc.size:
        kept[np.asarray(holes, dtype=np.int64).reshape(-1)] = False
    tris = fan_triangulate(kept_fvc, fvi)
    if str(mesh.GetOrientationAttr().Get(code) or "rightHanded") == "leftHanded":
        tris = tris[:, ::-1].copy()
    if not faces:
        return pts, tris
    return pts, tris, np.repeat(np.flatnonzero(kept), kept_fvc - 2), int(kept_fvc.size)


def _mesh_arrays(mesh, code, where: str):
    """(points, faceVertexCounts, faceVertexIndices) of a Mesh, checked: finite points, at least
    one face, faces of >= 3 vertices, indices in range."""
    pts = np.array(mesh.GetPointsAttr().Get(code) or [], dtype=np.float64).reshape(-1, 3)
    fvc = np.array(mesh.GetFaceVertexCountsAttr().Get(code) or [], dtype=np.int64).reshape(-1)
    fvi = np.array(mesh.GetFaceVertexIndicesAttr().Get(code) or [], dtype=np.int64).reshape(-1)
    bad = first_bad_row(pts)
    if bad is not None:
        raise UserError(f"{where}: points[{bad}] = {fmt_point(pts[bad])} is not finite")
    check_lengths(pts, "points", where)
    if pts.shape[0] == 0:
        raise UserError(f"{where}: the mesh has no points")
    if fvc.size == 0:
        raise UserError(f"{where}: the mesh has no faces (faceVertexCounts is empty)")
    if np.any(fvc < 3):
        i = int(np.flatnonzero(fvc < 3)[0])
        raise UserError(f"{where}: faceVertexCounts[{i}] = {int(fvc[i])}: a face needs at least 3 vertices")
    if int(fvc.sum()) != fvi.size:
        raise UserError(f"{where}: faceVertexCounts sum to {int(fvc.sum())} but faceVertexIndices has {fvi.size} entries")
    out = np.flatnonzero((fvi < 0) | (fvi >= pts.shape[0]))
    if out.size:
        i = int(out[0])
        raise UserError(f"{where}: faceVertexIndices[{i}] = {int(fvi[i])} is out of range (0..{pts.shape[0] - 1})")
    return pts, fvc, fvi


def read_root_mesh(prim, where: str, file: str, time, transforms: TransformReader):
    """The Mesh prim targeted by ``dftl:rootMesh`` on a curves prim, or None."""
    from pxr import UsdGeom

    rel = prim.GetRelationship("dftl:rootMesh")
    if not rel:
        return None
    targets = rel.GetForwardedTargets()
    if not targets:
        return None
    if len(targets) > 1:
        raise UserError(f"{where}: dftl:rootMesh has {len(targets)} targets; expected one Mesh")
    target = prim.GetStage().GetPrimAtPath(targets[0])
    if not target or not target.IsA(UsdGeom.Mesh):
        raise UserError(f"{where}: dftl:rootMesh -> {targets[0]}: not a Mesh prim")
    mesh_where = f"{file}: {target.GetPath()}"
    mesh = UsdGeom.Mesh(target)
    try:
        pts, fvc, fvi = _mesh_arrays(mesh, _code(time), mesh_where)
    except UserError as exc:
        raise UserError(f"{exc} (not a valid mesh for dftl:rootMesh)") from None
    triangles = fan_triangulate(fvc, fvi)
    corners = pts[triangles]
    if not np.linalg.norm(np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]), axis=1).any():
        n = len(triangles)
        raise UserError(f"{where}: dftl:rootMesh -> {target.GetPath()}: no non-degenerate triangle to bind the "
                        f"strands' roots to ({'its triangle has' if n == 1 else f'all {n} triangles have'} "
                        f"zero area)")
    points, deforming = points_sampler(mesh.GetPointsAttr(), pts.shape[0], mesh_where, time, pts)
    transform, moving = transforms.sampler(target, time)
    return MeshSource(str(target.GetPath()), triangles, points, transform, bool(deforming or moving))


def _friction(prim, where: str, warnings: list):
    from pxr import UsdPhysics

    value = read_values(prim, where, "collider", 24.0).get("dftl:friction")
    if value is not None:
        return float(value)
    material = bound_material(prim, where, warnings, "the collider's friction is dftl-warp's default")
    if material and material.GetPrim().HasAPI(UsdPhysics.MaterialAPI):
        value = UsdPhysics.MaterialAPI(material.GetPrim()).GetDynamicFrictionAttr().Get()
        if value is not None:
            return float(value)
    return None


def _enabled(api, code, where: str, warnings: list) -> bool:
    """``physics:collisionEnabled`` at ``code`` (the start frame): a value that is not a bool is an
    error; one that changes over time gets one warning (the value at ``code`` holds for the shot)."""
    attr = api.GetCollisionEnabledAttr()
    value = attr.Get(code)
    enabled = True if value is None else boolean(value, "physics:collisionEnabled", where)
    seen = {enabled} | {boolean(attr.Get(t), "physics:collisionEnabled", where) for t in attr.GetTimeSamples()}
    if len(seen) > 1:
        warnings.append(f"{where}: physics:collisionEnabled is time-sampled and changes over time: the value at "
                        f"{at_text(code)} ({'true' if enabled else 'false'}) holds for the whole shot "
                        f"(a collider cannot be switched on or off during it)")
    return enabled


def _axis(value, where: str) -> str:
    """A Capsule's ``axis`` token: "X", "Y" or "Z" (UsdGeomCapsule's tokens); anything else is an error."""
    axis = "Z" if value is None else value
    if not isinstance(axis, str) or axis not in ("X", "Y", "Z"):
        raise UserError(f"{where}: axis = {shown(axis)}: must be \"X\", \"Y\" or \"Z\" (UsdGeomCapsule's axis tokens)")
    return axis


def _has_area(pts: np.ndarray, tris: np.ndarray) -> np.ndarray:
    """Whether each triangle (T, 3) has an area: one whose corners are collinear to float32's
    precision (its doubled area at most :data:`DEGENERATE` of its longest edge squared) has none."""
    corners = pts[tris]
    cross = np.linalg.norm(np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]), axis=1)
    edges = np.linalg.norm(corners - np.roll(corners, 1, axis=1), axis=2).max(axis=1)
    return cross > DEGENERATE * edges * edges


#: a triangle whose doubled area is at most this fraction of its longest edge squared has no area
DEGENERATE = 1.0e-7


def _check_areas(pts, tris, faces, n_faces: int, where: str, warnings: list) -> None:
    """UserError when no face of a collider mesh has an area (all its faces are points or lines);
    one warning naming the first such faces (authored face indices) when some have none. ``faces``
    (T,): the authored face of each triangle ``tris`` (T, 3); ``n_faces``: the faces left after
    ``holeIndices``."""
    area = np.zeros(int(faces.max()) + 1 if faces.size else 0, dtype=bool)
    np.logical_or.at(area, faces, _has_area(pts, tris))
    flat = np.setdiff1d(np.unique(faces), np.flatnonzero(area))
    if not flat.size:
        return
    if flat.size == n_faces:
        raise UserError(f"{where}: no face of non-zero area ({'its face has' if n_faces == 1 else f'all {n_faces} faces have'} "
                        f"collinear or coincident corners): not a collider")
    first = ", ".join(str(int(i)) for i in flat[:5]) + (", ..." if flat.size > 5 else "")
    one = flat.size == 1
    warnings.append(f"{where}: {flat.size} of {plural(n_faces, 'face')} {'has' if one else 'have'} zero area "
                    f"(face{'' if one else 's'} {first}: collinear or coincident corners): "
                    f"{'it stops' if one else 'they stop'} no hair and can mislead which side is inside; remove "
                    f"{'it' if one else 'them'}")


def read_collider_prim(prim, file: str, time, warnings: list, transforms: TransformReader) -> ColliderPrim | None:
    """One prim with UsdPhysics.CollisionAPI -> ColliderPrim (None: disabled or unsupported)."""
    from pxr import UsdGeom, UsdPhysics

    where = f"{file}: {prim.GetPath()}"
    code = _code(time)
    if not _enabled(UsdPhysics.CollisionAPI(prim), code, where, warnings):
        return None

    def size(name, attr, low_open=True):
        """A size attribute at ``code``: a finite number > 0 (``low_open``) or >= 0, and not too large."""
        value = number(attr.Get(code), name, where)
        if not np.isfinite(value) or value < 0 or (low_open and value == 0):
            raise UserError(f"{where}: {name} = {shown(value)}: must be a finite number {'>' if low_open else '>='} 0")
        check_lengths([value], name, where, indexed=False)
        return value

    if prim.IsA(UsdGeom.Sphere):
        c = ColliderPrim(str(prim.GetPath()), "sphere", radius=size("radius", UsdGeom.Sphere(prim).GetRadiusAttr()))
    elif prim.IsA(UsdGeom.Capsule):
        cap = UsdGeom.Capsule(prim)
        c = ColliderPrim(
            str(prim.GetPath()), "capsule",
            radius=size("radius", cap.GetRadiusAttr()),
            height=size("height", cap.GetHeightAttr(), low_open=False),
            axis=_axis(cap.GetAxisAttr().Get(code), where),
        )
    elif prim.IsA(UsdGeom.Cube):
        c = ColliderPrim(str(prim.GetPath()), "box", half_extents=np.full(3, 0.5 * size("size", UsdGeom.Cube(prim).GetSizeAttr())))
    elif prim.IsA(UsdGeom.Mesh):
        mesh = UsdGeom.Mesh(prim)
        pts, tris, faces, n_faces = mesh_triangles(mesh, code, where, faces=True)
        _check_areas(pts, tris, faces, n_faces, where, warnings)
        c = ColliderPrim(str(prim.GetPath()), "mesh", mesh_points=pts, triangles=tris)
        sampler, deforming = points_sampler(mesh.GetPointsAttr(), pts.shape[0], where, time, pts)
        if deforming:
            c.points_sampler = sampler
    elif prim.GetTypeName() in GENERIC_TYPES:
        c = ColliderPrim(str(prim.GetPath()), str(prim.GetTypeName()), attributes=generic_attributes(prim, code))
    else:
        warnings.append(f"{where}: collider of type {prim.GetTypeName() or 'untyped'} is not supported; ignored")
        return None
    c.friction = _friction(prim, where, warnings)
    if c.kind == "mesh":  # the collider-scope dftl: attributes its shape reads (dftl:collisionSdf, ...)
        c.attributes.update({k: v for k, v in read_values(prim, where, "collider", 24.0).items() if k != "dftl:friction"})
    c.transform, c.animated = transforms.sampler(prim, time)
    _check_world_size(c, where)
    _note_size_animation(prim, c, where, time, warnings)
    return c


def _check_world_size(c: ColliderPrim, where: str) -> None:
    """UserError when the collider's position (the translation of its local-to-world transform, at
    any sample) or, under its scale, its size or mesh points are too large for float32
    (:func:`~dftl_warp.checks.check_lengths`)."""
    samples = getattr(c.transform, "values", None)
    matrices = np.asarray(c.transform(None) if samples is None else samples, dtype=np.float64).reshape(-1, 4, 4)
    check_lengths(matrices[:, 3, :3], "translate", where, indexed=False, world=" (its position in world space)")
    scale = float(np.linalg.norm(matrices[:, :3, :3], axis=2).max())
    for name in SIZE_ATTRIBUTES.get(c.kind, ()):
        size = 2.0 * float(c.half_extents[0]) if name == "size" else getattr(c, name)
        check_lengths([size * scale], name, where, indexed=False,
                      world=f" in world space ({size:g} under a scale of {scale:g})")
    if c.kind == "mesh":
        check_lengths(c.mesh_points * scale, "points", where,
                      world=f" in world space (under a scale of {scale:g})")


#: the size attributes of the built-in collider types, read once at the start frame
SIZE_ATTRIBUTES = {"sphere": ("radius",), "capsule": ("radius", "height"), "box": ("size",)}


def _note_size_animation(prim, c, where: str, time, warnings: list) -> None:
    """One warning when a collider's size changes over time while it keeps the size it has at
    ``time``: a time-sampled size attribute, or a scale that changes (a deforming mesh is re-read
    with its current scale every frame: not it)."""
    at = "the default time" if time is None else f"time {float(time):g}"
    parts = [f"{name} is time-sampled" for name in SIZE_ATTRIBUTES.get(c.kind, ())
             if prim.GetAttribute(name).ValueMightBeTimeVarying()]
    growth = scale_growth(c.transform, time)
    if growth > 1.0 + 1e-6 and c.points_sampler is None:
        parts.append(f"its scale changes over time (up to {growth:.4g}x its scale at {at})")
    if parts:
        warnings.append(f"{where}: {' and '.join(parts)}: the collider keeps its size at {at}; "
                        f"only its rotation and translation animate")
