"""Triangle-mesh colliders (:class:`TriangleMesh`): a :class:`warp.Mesh` per collider, made per
Control so that its points can deform per frame (:meth:`MeshColliders.set_points`, refitting its
BVH). USD: UsdGeomMesh (fan-triangulated), scale baked into the points; a mirroring scale turns
the faces back outward; ``dftl:collisionSdf`` and ``dftl:collisionSdfCellSize`` choose the signed
distance field (``sdf.py``). Kernel: ``kernels/features/mesh.py``.

Deforming meshes move inside the frame: from the points they had to the points set for the
frame's end, interpolated every substep (:meth:`MeshColliders.advance`: one launch over the points
and one BVH refit per moving mesh and substep, two in a frame's first: its two meshes swap roles;
docs/features.md, "Deforming bodies"). A mesh with a signed distance field keeps it (built once a
frame, at the frame's end, as before) while its points move at most its ``depth_band`` in the
frame; a frame in which they move farther collides through the interpolated exact queries (warned
once per collider).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import warp as wp

from ...core.precision import numpy_type
from ...kernels.features.mesh import MESH, mesh_substep_kernel
from ...checks import check_lengths
from ..base import finite_rows, nonnegative
from .base import ColliderShape
from .sdf import MeshFields, bounds, check_field_size, estimated_bytes, field_band, field_settings


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
        shape = cls(points=np.asarray(prim.mesh_points) * scale, indices=tris, sdf=attrs.get("dftl:collisionSdf"),
                    sdf_cell=attrs.get("dftl:collisionSdfCellSize"), **common)
        check_field_size(shape, "dftl:collisionSdfCellSize")   # FieldTooLarge: shape_from_prim names the file
        return shape

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


class _Motion:
    """A deforming mesh's points at the frame's start and end (device, local, m) and its two
    :class:`warp.Mesh`: ``pair`` (the collider's own, and a second one built from the same points,
    so that both have the same tree and any query answers alike on either). One holds the last
    substep's points (``pair[now]``, ``holds`` of the way through the frame: None when it holds
    none of this frame's start and end), the other the substep's before."""

    def __init__(self, mesh: wp.Mesh, shape):
        device = mesh.points.device
        self.start = wp.clone(mesh.points)
        self.end = wp.clone(mesh.points)
        second = wp.Mesh(points=wp.array(shape.points.astype(np.float32), dtype=wp.vec3, device=device),
                         indices=wp.array(shape.indices.reshape(-1), dtype=wp.int32, device=device))
        self.pair = (mesh, second)
        self.now = 0
        self.holds = None
        #: the frame's start (host), as :meth:`MeshColliders.set_points` gave it
        self.first = None


class MeshColliders:
    """The meshes of a Control's mesh colliders, per device collider (others: id 0): ``ids``,
    local bounds ``lower``/``upper`` (m, over the frame) and ``depth_band`` (m); ``fields``: the
    signed distance fields of those that use one (:class:`~.sdf.MeshFields`, rebuilt by
    :meth:`set_points`); ``prev_ids`` (the previous substep's mesh of those moving within the
    frame, else 0) and ``motion`` (m, how far their points moved in the substep). A moving mesh's
    ``ids`` entry names whichever of its two meshes holds the last substep's points
    (:meth:`mesh_now`); the collider's own (``meshes``) holds the points set while it does not move."""

    #: False: the two meshes of a moving collider keep their roles (the collider's own the current
    #: substep's points, the second the previous substep's), both written and refitted every
    #: substep, as before the ping-pong (a private switch: the reference of tests/test_mesh_pingpong.py
    #: and ``scripts/bench_features.py --mesh-two-refits``)
    _ping_pong = True

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
        self._shapes = {c: s for c, (_, s) in shapes.items()}
        #: device collider -> its points where the mesh is now (host float32, the last set)
        self._given = {c: s.points.astype(np.float32) for c, (_, s) in shapes.items()}
        #: device colliders whose points on the host may not be where the mesh is (after resync)
        self._stale: set = set()
        self._motions: dict = {}
        #: device colliders whose points are interpolated per substep this frame
        self.moving: set = set()
        self._alpha = 0.0
        self.prev_ids = wp.zeros(num_colliders, dtype=wp.uint64, device=device)
        #: zeros: no mesh moving (for queries of where hair is now, ``fill_struct(still=True)``)
        self.still_ids = wp.zeros(num_colliders, dtype=wp.uint64, device=device)
        self.motion = wp.zeros(num_colliders, dtype=model.scalar, device=device)
        self._frame_motion_host = np.zeros(num_colliders, dtype=np.float32)
        self.frame_motion = wp.zeros(num_colliders, dtype=wp.float32, device=device)

    def set_points(self, index: int, points, start=None) -> None:
        """The local points (P, 3), m, of mesh collider ``index`` (user order) at the end of the
        coming frame (set once a frame, before its substeps). The mesh moves to them through the
        frame from where it is (the points last set; ``start``, (P, 3) m, says where it is instead:
        needed after :meth:`resync`, else the mesh jumps to ``points`` at the frame's start)."""
        if index not in self.meshes:
            raise ValueError(f"collider {index} is not a mesh")
        c, mesh = self.meshes[index]
        pts = self._checked(index, points, "points", mesh)
        if start is not None:
            here = self._checked(index, start, "start points", mesh)
        else:
            here = pts if c in self._stale else self._given[c]
        self._stale.discard(c)
        self._given[c] = pts
        lo, hi = bounds(pts)
        moved = float(np.sqrt(np.max(np.sum((pts - here) ** 2, axis=1))))
        field = c in self.fields.fields
        fast = moved > float(self._shapes[c].depth_band)
        moving = moved > 0.0 and (fast or not field)
        if not (moving and self._ping_pong):
            # the mesh at the points (a moving mesh's substeps write their own: the ping-pong's first
            # writes the frame's start into this mesh, so these would go unread)
            mesh.points.assign(pts)
            mesh.refit()
        if field and fast:
            self.fields.fields[c].warn("moving", (
                f"its points move up to {moved:.3g} m in a frame, more than its depth band "
                f"{float(self._shapes[c].depth_band):.3g} m: its signed distance field, built once a frame, "
                "would let hair through, so such frames collide through exact mesh queries interpolated per "
                "substep (slower)"))
            self.fields.suspend(c)
        elif field:
            self.fields.build(c, lo, hi)
        if moving:
            motion = self._motions.get(c)
            if motion is None:
                motion = self._motions[c] = _Motion(mesh, self._shapes[c])
            motion.start.assign(here)
            motion.first = here   # the frame's start, for :meth:`rewind`
            motion.end.assign(pts)
            motion.holds = None   # a new start and end: the next substep writes both meshes
            self.moving.add(c)
            self._frame_motion_host[c] = moved
            lo, hi = np.minimum(lo, bounds(here)[0]), np.maximum(hi, bounds(here)[1])
            # ids/prev_ids: written by its substeps (they name the meshes they wrote)
        else:
            self.moving.discard(c)
            self._frame_motion_host[c] = 0.0
            # this collider's entries only: the others' are the device's (their substeps write them)
            self.ids[c:c + 1].assign(np.array([mesh.id], dtype=np.uint64))
            self.prev_ids[c:c + 1].assign(np.zeros(1, dtype=np.uint64))
        self.frame_motion.assign(self._frame_motion_host)
        if c not in self.moving:
            self.motion.zero_()
        # the host keeps the bounds it wrote (no read back from the device)
        self._lower_host[c], self._upper_host[c] = lo, hi
        self.lower.assign(self._lower_host)
        self.upper.assign(self._upper_host)

    def _checked(self, index, points, what, mesh) -> np.ndarray:
        pts = finite_rows(points, 3, f"mesh collider {index} {what}")
        check_lengths(pts, f"mesh collider {index} {what}", "", error=ValueError)   # Warp meshes are float32
        pts = pts.astype(np.float32)
        if pts.shape[0] != mesh.points.shape[0]:
            raise ValueError(f"mesh collider {index}: expected {mesh.points.shape[0]} {what}, got {pts.shape[0]}")
        return pts

    @property
    def stale(self) -> set:
        """Device colliders whose next :meth:`set_points` needs its ``start`` (after :meth:`resync`)."""
        return self._stale

    def resync(self) -> None:
        """Forget where the meshes are (after restoring a saved state): the next :meth:`set_points`
        takes its ``start``, or puts the mesh at its points from the frame's start."""
        self._stale = set(self._given)

    def advance(self, root_alpha: float) -> None:
        """This substep's points of the meshes that move within the frame, ``root_alpha`` of the way
        through it, and the previous substep's: one launch over the points per moving mesh.

        Ping-pong: the previous substep's points are those the last substep wrote, so the two
        meshes swap roles: the last substep's mesh becomes the previous one untouched, and the other
        gets this substep's points and one refit. A frame's first substep (``alpha_prev`` 0), or
        one after :meth:`set_points`, writes and refits both (the collider's own mesh the previous
        one): the mesh of the last frame's end holds ``start + 1 (end - start)``, not bit for bit
        the next frame's start (nor a ``start`` given after :meth:`resync`). So a frame of ``k``
        substeps refits ``k + 1`` times (``2 k + 1`` before, with the refit in :meth:`set_points`).

        CUDA graphs: the kernel writes the two meshes' ids into ``ids``/``prev_ids`` on the
        device, which the step reads when it runs, and a frame's substeps make the same choices
        whatever ran before it (the first writes both and starts on the same meshes), so a graph
        captured once replays them right, keyed by the moving meshes as before. The host's record of
        which mesh holds what (``_Motion.now``/``holds``) serves the substeps of one frame run in
        order; a replay does not update it, and the next frame starts afresh."""
        alpha_prev = self._alpha if root_alpha > self._alpha else 0.0
        self._alpha = float(root_alpha)
        for c in sorted(self.moving):
            motion = self._motions[c]
            if not self._ping_pong:
                now, before, both = 0, 1, True
            elif alpha_prev > 0.0 and motion.holds == alpha_prev:
                now, before, both = 1 - motion.now, motion.now, False
            else:
                now, before, both = 1, 0, True
            mesh, prev = motion.pair[now], motion.pair[before]
            wp.launch(mesh_substep_kernel(self.motion.dtype), dim=mesh.points.shape[0], device=self.motion.device,
                      inputs=[motion.start, motion.end, float(alpha_prev), float(root_alpha), self.frame_motion, c,
                              int(both), mesh.id, prev.id],
                      outputs=[mesh.points, prev.points, self.ids, self.prev_ids, self.motion])
            mesh.refit()
            if both:
                prev.refit()
            motion.now = now
            motion.holds = float(root_alpha) if root_alpha < 1.0 else None   # 1: start became end

    def rewind(self) -> None:
        """The meshes moving within the frame back at its start, to run the frame again (``--tolerance``'s
        sample runs a frame more than once on one Control): its last substep made their start its end
        (``mesh_substep_kernel``), so another run saw them stand still at the frame's end. The next
        substep writes both meshes from the start the frame's :meth:`set_points` gave."""
        for c in self.moving:
            motion = self._motions[c]
            motion.start.assign(motion.first)
            motion.holds = None
        self._alpha = 0.0

    def mesh_now(self, index: int) -> wp.Mesh:
        """The :class:`warp.Mesh` of mesh collider ``index`` (user order) that the step queries now:
        the last substep's points of a moving mesh, else the points set (reads the device's ids)."""
        c, mesh = self.meshes[index]
        now = int(self.ids.numpy()[c])
        return next((m for m in self._motions[c].pair if m.id == now), mesh) if c in self._motions else mesh

    def graph_variant(self) -> tuple:
        """What a frame's CUDA graph depends on: the meshes interpolated per substep (and the private
        switch of the two refits per substep)."""
        return tuple(sorted(self.moving)) + (() if self._ping_pong else ("two refits",))

    def fill_struct(self, st) -> None:
        st.collider_mesh = self.ids
        st.collider_mesh_prev = self.prev_ids
        st.collider_motion = self.motion
        st.collider_depth_band = self.depth_band
        st.collider_lower = self.lower
        st.collider_upper = self.upper
        self.fields.fill_struct(st)
