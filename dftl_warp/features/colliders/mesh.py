"""Triangle-mesh colliders (:class:`TriangleMesh`): a :class:`warp.Mesh` per collider, made per
Control so that its points can deform per frame (:meth:`MeshColliders.set_points`, refitting its
BVH). USD: UsdGeomMesh (fan-triangulated), scale baked into the points; a mirroring scale turns
the faces back outward. Kernel: ``kernels/features/mesh.py``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import warp as wp

from ...core.precision import numpy_type
from ...kernels.features.mesh import MESH
from ..base import nonnegative
from .base import ColliderShape


@dataclass(frozen=True, eq=False)
class TriangleMesh(ColliderShape):
    """A triangle mesh in its local coordinates: ``points`` (P, 3), m, ``indices`` (T, 3).

    Faces wind counter-clockwise seen from outside (their normal points out); an open mesh (a
    ground) has its inside behind its faces. The continuous test stops a particle whose path in
    the mesh's frame crosses the surface from the front within a step, however fast; particles
    found inside at the start of a step are pushed out from up to ``depth_band`` (m, default 1%
    of the mesh's bounding diagonal) plus their step's path below the surface. The closest-point
    query reaches that far, and its cost grows with it.
    """

    points: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    indices: np.ndarray = field(default_factory=lambda: np.zeros((0, 3), dtype=np.int32))
    depth_band: float | None = None
    kind = "meshes"
    kernel = MESH
    usd_kind = "mesh"

    def __post_init__(self):
        super().__post_init__()
        pts = np.asarray(self.points, dtype=np.float64).reshape(-1, 3)
        idx = np.asarray(self.indices, dtype=np.int64).reshape(-1, 3)
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
            band = 0.01 * float(np.linalg.norm(pts.max(0) - pts.min(0)))
        object.__setattr__(self, "depth_band", nonnegative(band, f"{self._label()} depth_band"))

    @classmethod
    def from_prim(cls, prim, position, rotation, scale, common):
        tris = np.asarray(prim.triangles)
        if np.prod(np.sign(scale)) < 0:
            tris = tris[:, ::-1]  # a mirror turns the faces inside out; turn them back
        return cls(points=np.asarray(prim.mesh_points) * scale, indices=tris, **common)

    @classmethod
    def make_device_data(cls, model, shapes, num_colliders):
        return MeshColliders(model, shapes, num_colliders)

    def fixed_bytes(self) -> int:
        return (self.points.size * 4 + self.indices.size * 4) * 2


class MeshColliders:
    """The meshes of a Control's mesh colliders, per device collider (others: id 0): ``ids``,
    local bounds ``lower``/``upper`` (m) and ``depth_band`` (m)."""

    def __init__(self, model, shapes: dict, num_colliders: int):
        device = model.device
        f = numpy_type(model.precision)
        ids = np.zeros(num_colliders, dtype=np.uint64)
        lower = np.zeros((num_colliders, 3))
        upper = np.zeros((num_colliders, 3))
        band = np.zeros(num_colliders, dtype=f)
        #: user index -> (device index, wp.Mesh)
        self.meshes = {}
        for c, (user_index, s) in shapes.items():
            mesh = wp.Mesh(points=wp.array(s.points.astype(np.float32), dtype=wp.vec3, device=device),
                           indices=wp.array(s.indices.reshape(-1), dtype=wp.int32, device=device))
            self.meshes[user_index] = (c, mesh)
            ids[c] = mesh.id
            lower[c], upper[c] = s.points.min(0), s.points.max(0)
            band[c] = s.depth_band
        self._ftype = f
        self.ids = wp.array(ids, dtype=wp.uint64, device=device)
        self.lower = wp.array(lower.astype(f), dtype=model.vec3, device=device)
        self.upper = wp.array(upper.astype(f), dtype=model.vec3, device=device)
        self.depth_band = wp.array(band, dtype=model.scalar, device=device)

    def set_points(self, index: int, points) -> None:
        """New local points (P, 3), m, of mesh collider ``index`` (user order), from now on."""
        if index not in self.meshes:
            raise ValueError(f"collider {index} is not a mesh")
        c, mesh = self.meshes[index]
        pts = np.asarray(points, dtype=np.float32).reshape(-1, 3)
        if pts.shape[0] != mesh.points.shape[0]:
            raise ValueError(f"mesh collider {index}: expected {mesh.points.shape[0]} points, got {pts.shape[0]}")
        mesh.points.assign(pts)
        mesh.refit()
        lower, upper = self.lower.numpy(), self.upper.numpy()
        lower[c], upper[c] = pts.min(0).astype(self._ftype), pts.max(0).astype(self._ftype)
        self.lower.assign(lower)
        self.upper.assign(upper)

    def fill_struct(self, st) -> None:
        st.collider_mesh = self.ids
        st.collider_depth_band = self.depth_band
        st.collider_lower = self.lower
        st.collider_upper = self.upper
