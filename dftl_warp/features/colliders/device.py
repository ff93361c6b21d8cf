"""Colliders on the device: the Model's immutable data (:func:`build`, :class:`ColliderData`) and
the Control's per-frame poses (:class:`ColliderControl`).

Device colliders are sorted by shape kind in registration order (then in the user's order), so
that each kind's colliders are one index range; ``order`` maps the user's index to the device's.
Poses are ``(p, q xyzw)`` rows relative to ``model.origin`` (m).
"""

from __future__ import annotations

import numpy as np
import warp as wp

from ...core.precision import numpy_type
from ...kernels.features.collide import collider_pose_kernel, transform_type
from ...checks import check_lengths
from ..base import finite_rows, quat_rotate, quaternion_rows
from .base import SHAPES, Colliders


def inverse_poses(poses) -> np.ndarray:
    """Inverses of (C, 7) poses ``(p, q xyzw)``."""
    poses = np.asarray(poses, dtype=np.float64).reshape(-1, 7)
    conj = poses[:, 3:] * np.array([-1.0, -1.0, -1.0, 1.0])
    return np.concatenate([-quat_rotate(conj, poses[:, :3]), conj], axis=1)


def hemisphere_signs(poses, reference) -> np.ndarray:
    """(C, 1) signs that put each (C, 7) pose row's quaternion on the hemisphere of
    ``reference``'s (the same rotations; a path between them then turns the short way)."""
    dots = np.sum(np.asarray(poses)[:, 3:] * np.asarray(reference)[:, 3:], axis=1)
    return np.where(dots < 0.0, -1.0, 1.0)[:, None]


class ColliderData:
    """The Model's collider data: ``colliders`` (the feature), ``order`` (device index of each user
    collider), ``kinds`` (present kinds, device order), ``bounds`` (kind ``j`` owns device colliders
    ``bounds[j]:bounds[j + 1]``), device vectors ``particle_radius`` (m, per slot), ``size``,
    ``axis``, ``friction`` per device collider, and ``rest_pose`` (C, 7) numpy."""

    def __init__(self, colliders, order, kinds, bounds, arrays, rest_pose):
        self.colliders = colliders
        self.order = order
        self.kinds = kinds
        self.bounds = bounds
        self.arrays = arrays
        self.rest_pose = rest_pose


def build(colliders: Colliders, ctx, widths=None) -> ColliderData:
    """Device data of ``colliders`` for a model being built (``ctx``: the model's fields);
    ``widths``: hair diameters (m), one or one per point: the contact distance is half of it."""
    lay, ftype, scalar, vec3, device = ctx["layout"], ctx["ftype"], ctx["scalar"], ctx["vec3"], ctx["device"]
    points = ctx["points"]

    def arr(a, dtype):
        return wp.array(np.ascontiguousarray(a), dtype=dtype, device=device)

    radius = np.zeros(lay.num_slots, dtype=ftype)
    if widths is not None:
        w = np.asarray(widths, dtype=np.float64).reshape(-1)
        if w.size == 1:
            w = np.full(len(points), float(w[0]))
        if w.shape != (len(points),) or not np.isfinite(w).all() or np.any(w < 0):
            raise ValueError(f"widths must be one value or one per point ({len(points)}), finite and >= 0")
        radius[lay.slot_of_point] = 0.5 * w
    shapes = colliders.shapes
    kinds_order = list(SHAPES)
    device_order = sorted(range(len(shapes)), key=lambda i: (kinds_order.index(shapes[i].kind), i))
    order = np.empty(len(shapes), dtype=np.int64)
    order[device_order] = np.arange(len(shapes))
    ordered = [shapes[i] for i in device_order]
    sizes, axes = zip(*(s.size_axis() for s in ordered))
    if ctx["precision"] == "float32":   # finite in float64, inf (or its square inf) in the model
        for i, s in enumerate(shapes):
            check_lengths([s.size_axis()[0]], f"collider {i} ({s.kind}) size", "", indexed=False, error=ValueError)
            check_lengths([s.position], f"collider {i} ({s.kind}) position", "", indexed=False, error=ValueError)
    arrays = {
        "particle_radius": arr(radius, scalar),
        "size": arr(np.array(sizes, dtype=ftype), vec3),
        "axis": arr(np.array(axes, dtype=ftype), vec3),
        "friction": arr(np.array([s.friction for s in ordered], dtype=ftype), scalar),
    }
    rest_pose = np.array([np.concatenate([s.position - ctx["origin"], s.rotation]) for s in ordered])
    kinds = [k for k in kinds_order if any(s.kind == k for s in ordered)]
    bounds = [0]
    for k in kinds:
        bounds.append(bounds[-1] + sum(s.kind == k for s in ordered))
    return ColliderData(colliders, order, tuple(kinds), tuple(bounds), arrays,
                        rest_pose.reshape(-1, 7).astype(ftype))


class ColliderControl:
    """Collider poses of a Control: ``pose_start``/``pose_end`` of the frame, and the current and
    previous substep's ``pose``/``pose_prev`` with their inverses (updated by each step), per
    device collider; ``kind_data``: the data of kinds that have their own (meshes)."""

    def __init__(self, model, data: ColliderData):
        self.model = model
        self.data = data
        device = model.device
        transform = transform_type(model.scalar)
        rest = data.rest_pose
        self.pose_start, self.pose_end, self.pose, self.pose_prev = (
            wp.array(rest, dtype=transform, device=device) for _ in range(4))
        #: the Hermite deviations ``T rate - chord`` of the poses' rates at the frame's start and
        #: end (the pose's 7 components; zeros on the linear path)
        self.deviation_start, self.deviation_end = (
            wp.zeros(len(rest), dtype=transform, device=device) for _ in range(2))
        #: whether this frame's poses follow the C1 path (rates were given)
        self.curved = False
        inverse = inverse_poses(rest).astype(rest.dtype)
        self.inv_pose, self.inv_pose_prev = (wp.array(inverse, dtype=transform, device=device) for _ in range(2))
        self._synced = False
        self.kind_data = {}
        for kind in data.kinds:
            mine = {int(data.order[i]): (i, s) for i, s in enumerate(data.colliders.shapes) if s.kind == kind}
            made = SHAPES[kind].make_device_data(model, mine, len(rest))
            if made is not None:
                self.kind_data[kind] = made

    def set_poses(self, start, end=None, *, rate_start=None, rate_end=None,
                  frame_duration: float | None = None) -> None:
        """Poses of all colliders for this frame: (C, 7) rows ``(px, py, pz, qx, qy, qz, qw)``,
        world space (m), in the Colliders' order; ``end`` defaults to ``start``.

        ``rate_start``/``rate_end`` (C, 7), the rows' time derivatives at the frame's start and
        end (m/s for the translation, 1/s for the quaternion's components, of the rows as given),
        with ``frame_duration`` (s), put the colliders on the roots' C1 path inside the frame
        (:func:`~dftl_warp.kernels.features.collide.collider_pose_kernel`); without them they move
        linearly (translation lerp, rotation slerp).

        The first call (and the first after :meth:`resync`) also places the colliders at
        ``start`` for the previous substep, so that they do not sweep from their rest pose."""
        m = self.model
        n = len(self.data.colliders.shapes)
        f = numpy_type(m.precision)
        rows = {}
        for name, given in (("start", start), ("end", start if end is None else end)):
            r = finite_rows(given, 7, f"collider poses ({name})")
            if r.shape[0] != n:
                raise ValueError(f"expected {n} collider poses, got {r.shape[0]}")
            quaternion_rows(r, f"collider poses ({name})")
            r[:, :3] -= m.origin
            rows[name] = r
        # the end's quaternion on the start's hemisphere (the same rotation; the path then turns
        # the short way), its rate with it
        flip = hemisphere_signs(rows["end"], rows["start"])
        rows["end"][:, 3:] *= flip
        norms = {k: np.linalg.norm(r[:, 3:], axis=1, keepdims=True) for k, r in rows.items()}
        for k, r in rows.items():
            r[:, 3:] /= norms[k]
        for dst, r in ((self.pose_start, rows["start"]), (self.pose_end, rows["end"])):
            device_rows = np.empty_like(r)
            device_rows[self.data.order] = r
            dst.assign(device_rows.astype(f))
            if dst is self.pose_start and not self._synced:
                inverse = inverse_poses(device_rows).astype(f)
                for a, v in ((self.pose, device_rows), (self.pose_prev, device_rows), (self.inv_pose, inverse),
                             (self.inv_pose_prev, inverse)):
                    a.assign(v.astype(f))
        self._synced = True
        if rate_start is None and rate_end is None and frame_duration is None:
            if self.curved:
                self.deviation_start.zero_()
                self.deviation_end.zero_()
            self.curved = False
            return
        if rate_start is None or rate_end is None or frame_duration is None or not frame_duration > 0:
            raise ValueError("collider pose rates: give rate_start, rate_end and a positive frame_duration together")
        chord = rows["end"] - rows["start"]
        for dst, rate, k, sign in ((self.deviation_start, rate_start, "start", 1.0),
                                   (self.deviation_end, rate_end, "end", flip)):
            rate = np.asarray(rate, dtype=np.float64).reshape(-1, 7).copy()
            if rate.shape[0] != n or not np.isfinite(rate).all():
                raise ValueError(f"collider pose rates must be {n} finite rows of 7")
            rate[:, 3:] *= sign / norms[k]
            device_rows = np.empty_like(rate)
            device_rows[self.data.order] = frame_duration * rate - chord
            dst.assign(device_rows.astype(f))
        self.curved = True

    def resync(self) -> None:
        """Forget the colliders' previous pose and where the meshes are (after restoring a saved state)."""
        self._synced = False
        meshes = self.kind_data.get("meshes")
        if meshes is not None:
            meshes.resync()

    def mesh_stale(self, index: int) -> bool:
        """Whether mesh collider ``index`` needs its frame's ``start`` points with the next
        :meth:`set_mesh_points` (after :meth:`resync`)."""
        meshes = self.kind_data.get("meshes")
        return meshes is not None and index in meshes.meshes and meshes.meshes[index][0] in meshes.stale

    def set_mesh_points(self, index: int, points, start=None) -> None:
        """Local points (P, 3), m, of mesh collider ``index`` (Colliders order) at the coming frame's
        end: the mesh moves to them through the frame, from ``start`` when given, else from the
        points last set (:meth:`MeshColliders.set_points <.mesh.MeshColliders.set_points>`)."""
        meshes = self.kind_data.get("meshes")
        if meshes is None:
            raise ValueError(f"collider {index} is not a mesh")
        meshes.set_points(index, points, start=start)

    def graph_variant(self) -> tuple:
        """What a frame's CUDA graph depends on beyond its inputs: the meshes moving per substep."""
        meshes = self.kind_data.get("meshes")
        return () if meshes is None else meshes.graph_variant()

    def advance(self, root_alpha: float) -> None:
        """This substep's poses: ``alpha`` of the way from the frame's start to its end (on the
        C1 path when this frame's poses came with rates), and the points of the meshes moving
        within the frame."""
        m = self.model
        meshes = self.kind_data.get("meshes")
        if meshes is not None:
            meshes.advance(root_alpha)
        wp.launch(collider_pose_kernel(m.scalar, self.curved), dim=self.pose.shape[0], device=m.device,
                  inputs=[self.pose_start, self.pose_end, self.deviation_start, self.deviation_end, root_alpha],
                  outputs=[self.pose, self.pose_prev, self.inv_pose, self.inv_pose_prev])

    def fill_struct(self, st, still: bool = False) -> None:
        """The colliders' fields of the step struct; ``still``: as if nothing had moved since the last
        substep (previous poses the current ones, meshes not moving: a query of where hair is now)."""
        d, a = self.data, self.data.arrays
        st.particle_radius = a["particle_radius"]
        st.collider_pose = self.pose
        st.collider_inv_pose = self.inv_pose
        st.collider_inv_pose_prev = self.inv_pose_prev
        st.collider_size = a["size"]
        st.collider_axis = a["axis"]
        st.collider_friction = a["friction"]
        st.collider_iterations = int(d.colliders.iterations)
        st.collider_bounds = wp.types.vector(len(d.bounds), wp.int32)(*d.bounds)
        for made in self.kind_data.values():
            made.fill_struct(st)
        if still:
            st.collider_inv_pose_prev = self.inv_pose
            meshes = self.kind_data.get("meshes")
            if meshes is not None:
                st.collider_mesh_prev = meshes.still_ids


def fixed_bytes(data: ColliderData, precision: str) -> int:
    """Device bytes of the colliders that do not grow with the hair."""
    f = np.dtype(precision).itemsize
    shapes = data.colliders.shapes
    return len(shapes) * (6 * 7 * f + 4 * 3 * f + 2 * f + 8) + sum(s.fixed_bytes() for s in shapes)
