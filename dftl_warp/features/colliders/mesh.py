"""Triangle-mesh colliders (:class:`TriangleMesh`): a :class:`warp.Mesh` per collider, made per
Control so that its points can deform per frame (:meth:`MeshColliders.set_points`, refitting its
BVH). USD: UsdGeomMesh (fan-triangulated), scale baked into the points; a mirroring scale turns
the faces back outward; ``dftl:collisionSdf`` and ``dftl:collisionSdfCellSize`` choose the signed
distance field (``sdf.py``). Kernel: ``kernels/features/mesh.py``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import warp as wp

from ...core.precision import numpy_type
from ...kernels.features.mesh import MESH
from ..base import finite_rows, nonnegative
from .base import ColliderShape
from .sdf import MeshFields, bounds, estimated_bytes, field_band, field_settings


@dataclass(frozen=True, eq=False)
class TriangleMesh(ColliderShape):
    """A triangle mesh in its local coordinates: ``points`` (P, 3), m, ``indices`` (T, 3).

    Faces wind counter-clockwise seen from outside (their normal points out); an open mesh (a
    ground) has its inside behind its faces. The continuous test stops a particle whose path in
    the mesh's frame crosses the surface from the front within a step, however fast; particles
    found inside at the start of a step are pushed out from up to ``depth_band`` (m, default 1%
    of the mesh's bounding diagonal) plus their step's path below the surface. The closest-point
    query reaches that far in every collision round, and its cost grows with it.

    ``sdf``: collide through a signed distance field rebuilt whenever the points change (True),
    through exact mesh queries (False), or the field from ``SDF_MIN_TRIANGLES`` triangles on
    (None); ``sdf_cell`` (m, default the mean edge length) and ``sdf_tolerance`` (m, the largest
    estimated interpolation error where the field answers; default 1/16 cell): see ``sdf.py``.
    """

    points: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    indices: np.ndarray = field(default_factory=lambda: np.zeros((0, 3), dtype=np.int32))
    depth_band: float | None = None
    sdf: bool | None = None
    sdf_cell: float | None = None
    sdf_tolerance: float | None = None
    kind = "meshes"
    kernel = MESH
    usd_kind = "mesh"

    def __post_init__(self):
        super().__post_init__()
        pts = np.asarray(self.points, dtype=np.float64)
        if pts.ndim != 2 or pts.shape[1] != 3:
            raise ValueError(f"{self._label()} points must be an array of shape (P, 3), got shape {pts.shape}")
        idx = np.asarray(self.indices)
        if idx.size and not np.issubdtype(idx.dtype, np.integer):
            raise ValueError(f"{self._label()} indices must be integers, got dtype {idx.dtype}")
        if (idx.ndim == 2 and idx.shape[1] != 3) or idx.ndim > 2 or idx.size % 3:
            raise ValueError(f"{self._label()} indices must be (T, 3) or a flat list of a multiple of 3, "
                             f"got shape {idx.shape}")
        idx = idx.astype(np.int64).reshape(-1, 3)
        if idx.size == 0 or pts.size == 0:
            raise ValueError(f"{self._label()} has no triangles")
        if idx.min() < 0 or idx.max() >= len(pts):
            raise ValueError(f"{self._label()} indices reference points outside 0..{len(pts) - 1}")
        if not np.isfinite(pts).all():
            raise ValueError(f"{self._label()} point {int(np.flatnonzero(~np.isfinite(pts).all(1))[0])} is not finite")
        object.__setattr__(self, "points", pts)
        object.__setattr__(self, "indices", idx.astype(np.int32))
        band = self.depth_band
        if band is None:
            lo, hi = bounds(pts)
            band = 0.01 * float(np.linalg.norm(hi - lo))
        object.__setattr__(self, "depth_band", nonnegative(band, f"{self._label()} depth_band"))
        if self.sdf is not None:
            if not isinstance(self.sdf, (bool, np.bool_)):
                raise ValueError(f"{self._label()} sdf must be True, False or None, got {self.sdf!r}")
            object.__setattr__(self, "sdf", bool(self.sdf))
        for name in ("sdf_cell", "sdf_tolerance"):
            value = getattr(self, name)
            if value is not None and not (np.isfinite(float(value)) and float(value) > 0):
                raise ValueError(f"{self._label()} {name} must be a finite length > 0, got {value!r}")

    @property
    def uses_sdf(self) -> bool:
        """Whether the mesh collides through a signed distance field (``sdf``, else its size)."""
        return field_settings(self)[0]

    @classmethod
    def from_prim(cls, prim, position, rotation, scale, common):
        tris = np.asarray(prim.triangles)
        if np.prod(np.sign(scale)) < 0:
            tris = tris[:, ::-1]  # a mirror turns the faces inside out; turn them back
        attrs = prim.attributes
        return cls(points=np.asarray(prim.mesh_points) * scale, indices=tris, sdf=attrs.get("dftl:collisionSdf"),
                   sdf_cell=attrs.get("dftl:collisionSdfCellSize"), **common)

    @classmethod
    def make_device_data(cls, model, shapes, num_colliders):
        return MeshColliders(model, shapes, num_colliders)

    def fixed_bytes(self) -> int:
        mesh = (self.points.size * 4 + self.indices.size * 4) * 2
        uses, cell, _ = field_settings(self)
        if not uses:
            return mesh
        # the field's band for hair of radius 0 (the hair's radius adds little)
        return mesh + estimated_bytes(self.points, self.indices, cell, field_band(self.depth_band, 0.0, cell))


class MeshColliders:
    """The meshes of a Control's mesh colliders, per device collider (others: id 0): ``ids``,
    local bounds ``lower``/``upper`` (m) and ``depth_band`` (m); ``fields``: the signed distance
    fields of those that use one (:class:`~.sdf.MeshFields`, rebuilt by :meth:`set_points`)."""

    def __init__(self, model, shapes: dict, num_colliders: int):
        device = model.device
        f = numpy_type(model.precision)
        ids = np.zeros(num_colliders, dtype=np.uint64)
        lower = np.zeros((num_colliders, 3))
        upper = np.zeros((num_colliders, 3))
        band = np.zeros(num_colliders, dtype=f)
        #: user index -> (device index, wp.Mesh)
        self.meshes = {}
        with_field = []
        for c, (user_index, s) in shapes.items():
            mesh = wp.Mesh(points=wp.array(s.points.astype(np.float32), dtype=wp.vec3, device=device),
                           indices=wp.array(s.indices.reshape(-1), dtype=wp.int32, device=device))
            self.meshes[user_index] = (c, mesh)
            ids[c] = mesh.id
            lower[c], upper[c] = bounds(s.points)
            band[c] = s.depth_band
            if s.uses_sdf:
                with_field.append((c, s, mesh))
        self.ids = wp.array(ids, dtype=wp.uint64, device=device)
        self._lower_host, self._upper_host = lower.astype(f), upper.astype(f)
        self.lower = wp.array(self._lower_host, dtype=model.vec3, device=device)
        self.upper = wp.array(self._upper_host, dtype=model.vec3, device=device)
        self.depth_band = wp.array(band, dtype=model.scalar, device=device)
        radius = model.feature_data.collider_data.arrays["particle_radius"].numpy()
        self.fields = MeshFields(device, num_colliders, with_field, float(radius.max(initial=0.0)))

    def set_points(self, index: int, points) -> None:
        """New local points (P, 3), m, of mesh collider ``index`` (user order), from now on."""
        if index not in self.meshes:
            raise ValueError(f"collider {index} is not a mesh")
        c, mesh = self.meshes[index]
        pts = finite_rows(points, 3, f"mesh collider {index} points").astype(np.float32)
        if pts.shape[0] != mesh.points.shape[0]:
            raise ValueError(f"mesh collider {index}: expected {mesh.points.shape[0]} points, got {pts.shape[0]}")
        mesh.points.assign(pts)
        mesh.refit()
        lo, hi = bounds(pts)
        # the host keeps the bounds it wrote (no read back from the device)
        self._lower_host[c], self._upper_host[c] = lo, hi
        self.lower.assign(self._lower_host)
        self.upper.assign(self._upper_host)
        if c in self.fields.fields:
            self.fields.build(c, lo, hi)

    def fill_struct(self, st) -> None:
        st.collider_mesh = self.ids
        st.collider_depth_band = self.depth_band
        st.collider_lower = self.lower
        st.collider_upper = self.upper
        self.fields.fill_struct(st)
