"""Device data of the optional features, split like the rest of the API:

- :class:`ModelFeatures` (immutable, in the :class:`~dftl_warp.core.model.Model`): collider geometry
  and friction, hair radii, drag rates, rest-shape frames, root bindings, grid size;
- :class:`FeatureControl` (in the :class:`~dftl_warp.core.state.Control`, as ``control.features``):
  what a scene animates per frame -- collider poses, mesh points, wind velocity and time,
  bound-root mesh points;
- :class:`FeatureStep` (in the solver): the scratch grid and the launches of one step.

All device coordinates are relative to ``model.origin`` like the strands'.
"""

from __future__ import annotations

import numpy as np
import warp as wp

from .objects import (
    SHAPE_KINDS,
    Colliders,
    Drag,
    HairHair,
    RootBinding,
    ShapeRetention,
    Wind,
    check_features,
    feature_flags,
    find,
)
from ..kernels.features.binding import bind_roots_kernel, closest_face
from ..kernels.features.collide import collider_pose_kernel, transform_type
from ..kernels.solvers.featured import feature_struct
from ..kernels.features.grid import grid_bounds_kernel, grid_reset_kernel, grid_splat_kernel
from ..core.precision import numpy_type


# -- numpy quaternions (x, y, z, w), mirroring kernels/shape.py --------------------------------------


def _qmul(a, b):
    ax, ay, az, aw = np.moveaxis(a, -1, 0)
    bx, by, bz, bw = np.moveaxis(b, -1, 0)
    return np.stack([aw * bx + ax * bw + ay * bz - az * by,
                     aw * by - ax * bz + ay * bw + az * bx,
                     aw * bz + ax * by - ay * bx + az * bw,
                     aw * bw - ax * bx - ay * by - az * bz], axis=-1)


def _qrot(q, v):
    u, w = q[..., :3], q[..., 3:]
    t = 2.0 * np.cross(u, v)
    return v + w * t + np.cross(u, t)


def _qbetween(a, b):
    c = np.sum(a * b, axis=-1, keepdims=True)
    v = np.cross(a, b)
    q = np.concatenate([v, 1.0 + c], axis=-1)
    opposite = c[..., 0] < -0.999999
    if np.any(opposite):
        ao = a[opposite]
        axis = np.cross(ao, [1.0, 0.0, 0.0])
        small = np.linalg.norm(axis, axis=-1) < 1e-3
        axis[small] = np.cross(ao[small], [0.0, 1.0, 0.0])
        axis /= np.linalg.norm(axis, axis=-1, keepdims=True)
        q[opposite] = np.concatenate([axis, np.zeros((len(axis), 1))], axis=-1)
    return q / np.linalg.norm(q, axis=-1, keepdims=True)


def _inverse_poses(poses):
    """Inverses of (C, 7) poses ``(p, q xyzw)``."""
    poses = np.asarray(poses, dtype=np.float64).reshape(-1, 7)
    conj = poses[:, 3:] * np.array([-1.0, -1.0, -1.0, 1.0])
    return np.concatenate([-_qrot(conj, poses[:, :3]), conj], axis=1)


def rest_frames(points, counts):
    """Rest frame of each strand's first segment (S, 4) and each particle's rest direction in
    the frame of the segment before it (N, 3), by parallel transport along the rest shape."""
    points = np.asarray(points, dtype=np.float64)
    counts = np.asarray(counts, dtype=np.int64)
    starts = np.zeros(len(counts), dtype=np.int64)
    np.cumsum(counts[:-1], out=starts[1:])
    ex = np.array([1.0, 0.0, 0.0])
    rest_dir = np.tile(ex, (len(points), 1))
    frame = np.tile([0.0, 0.0, 0.0, 1.0], (len(counts), 1))
    direction = np.tile(ex, (len(counts), 1))
    first = np.zeros((len(counts), 4))
    first[:, 3] = 1.0
    for i in range(1, int(counts.max(initial=0))):
        s = np.flatnonzero(counts > i)
        seg = points[starts[s] + i] - points[starts[s] + i - 1]
        length = np.linalg.norm(seg, axis=1)
        ok = length > 0
        t = np.where(ok[:, None], seg / np.where(ok, length, 1.0)[:, None], direction[s])
        if i == 1:
            q = _qbetween(np.broadcast_to(ex, t.shape), t)
            first[s] = q
            frame[s] = q
        else:
            conj = frame[s] * np.array([-1.0, -1.0, -1.0, 1.0])
            rest_dir[starts[s] + i] = _qrot(conj, t)
            q = _qmul(_qbetween(direction[s], t), frame[s])
            frame[s] = np.where(ok[:, None], q / np.linalg.norm(q, axis=1, keepdims=True), frame[s])
        direction[s] = t
    return first, rest_dir


def _per_strand(value, num_strands, what):
    a = np.asarray(value, dtype=np.float64)
    if a.ndim == 0:
        return np.full(num_strands, float(a))
    if a.shape != (num_strands,):
        raise ValueError(f"{what}: expected one value or {num_strands} (one per strand), got shape {a.shape}")
    return a


def _poses(shapes, origin):
    """(C, 7) device poses (p - origin, q xyzw) of shapes at rest."""
    return np.array([np.concatenate([s.position - origin, s.rotation]) for s in shapes]).reshape(-1, 7)


class ModelFeatures:
    """The immutable device data of a model's features (see :func:`build`)."""

    def __init__(self, features, flags, arrays, colliders, collider_order, binding, grid_shape, grid_cell):
        self.features = features
        self.flags = flags
        self.arrays = arrays
        #: the Colliders feature (shapes in the user's order), or None
        self.colliders = colliders
        #: device collider index of each user collider
        self.collider_order = collider_order
        self.binding = binding
        self.grid_shape = grid_shape
        self.grid_cell = grid_cell

    def bytes_per_particle(self, precision: str) -> float:
        """Device bytes per particle of the features' per-particle arrays (model and scratch)."""
        f = np.dtype(precision).itemsize
        b = 0
        if "shape" in self.flags:
            b += 3 * f
        if self.flags & set(SHAPE_KINDS):
            b += f
        return b

    def bytes_per_strand(self, precision: str) -> float:
        f = np.dtype(precision).itemsize
        b = 0
        if "drag" in self.flags:
            b += f
        if "shape" in self.flags:
            b += 5 * f
        if self.binding is not None:
            b += 12 + 3 * f
        return b

    def grid_bytes(self, precision: str) -> int:
        if self.grid_shape is None:
            return 0
        return int(np.prod(self.grid_shape)) * 4 * np.dtype(precision).itemsize


def build(model_args, features, *, widths=None):
    """Device data for ``features`` of a model being built (``model_args``: the Model's fields)."""
    features = check_features(features)
    flags = feature_flags(features)
    m = model_args
    device, precision, lay = m["device"], m["precision"], m["layout"]
    scalar, vec3 = m["scalar"], m["vec3"]
    ftype = numpy_type(precision)
    counts = m["counts"]
    points = m["points"]  # world, input order
    num_strands = len(counts)
    order = lay.strand_order
    arrays = {}

    def arr(a, dtype):
        return wp.array(np.ascontiguousarray(a), dtype=dtype, device=device)

    colliders = find(features, Colliders)
    collider_order = None
    if colliders is not None and colliders.shapes:
        radius = np.zeros(lay.num_slots, dtype=ftype)
        if widths is not None:
            w = np.asarray(widths, dtype=np.float64).reshape(-1)
            if w.size == 1:
                w = np.full(len(points), float(w[0]))
            if w.shape != (len(points),) or not np.isfinite(w).all() or np.any(w < 0):
                raise ValueError(f"widths must be one value or one per point ({len(points)}), finite and >= 0")
            radius[lay.slot_of_point] = 0.5 * w
        arrays["particle_radius"] = arr(radius, scalar)
        shapes = colliders.shapes
        collider_order = np.array(sorted(range(len(shapes)), key=lambda i: (SHAPE_KINDS.index(shapes[i].kind), i)))
        device_index = np.empty(len(shapes), dtype=np.int64)
        device_index[collider_order] = np.arange(len(shapes))
        ordered = [shapes[i] for i in collider_order]
        sizes, axes = zip(*(s.size_axis() for s in ordered))
        arrays["collider_size"] = arr(np.array(sizes, dtype=ftype), vec3)
        arrays["collider_axis"] = arr(np.array(axes, dtype=ftype), vec3)
        arrays["collider_friction"] = arr(np.array([s.friction for s in ordered], dtype=ftype), scalar)
        arrays["collider_depth_band"] = arr(
            np.array([getattr(s, "depth_band", 0.0) for s in ordered], dtype=ftype), scalar)
        arrays["collider_rest_pose"] = _poses(ordered, m["origin"]).astype(ftype)
        ranges = {}
        kinds = [s.kind for s in ordered]
        for kind in SHAPE_KINDS:
            idx = [i for i, k in enumerate(kinds) if k == kind]
            ranges[kind] = (idx[0], idx[-1] + 1) if idx else (0, 0)
        arrays["collider_ranges"] = ranges
        collider_order = device_index

    drag = find(features, Drag)
    if drag is not None:
        arrays["drag"] = arr(_per_strand(drag.rate, num_strands, "drag rate")[order].astype(ftype), scalar)

    shape = find(features, ShapeRetention)
    if shape is not None:
        stiffness = _per_strand(shape.stiffness, num_strands, "shape retention stiffness")
        first, rest_dir = rest_frames(points, counts)
        dirs = np.zeros((lay.num_slots, 3), dtype=ftype)
        dirs[lay.slot_of_point] = rest_dir
        arrays["shape_stiffness"] = arr(stiffness[order].astype(ftype), scalar)
        arrays["shape_rest_frame"] = arr(first[order].astype(ftype), wp.types.quaternion(dtype=scalar))
        arrays["shape_rest_dir"] = arr(dirs, vec3)

    binding = None
    rb = find(features, RootBinding)
    if rb is not None:
        if rb.triangles is None:
            starts = np.zeros(num_strands, dtype=np.int64)
            np.cumsum(counts[:-1], out=starts[1:])
            mesh = wp.Mesh(points=wp.array(rb.points.astype(np.float32), dtype=wp.vec3, device=device),
                           indices=wp.array(rb.indices.reshape(-1), dtype=wp.int32, device=device))
            face = wp.zeros(num_strands, dtype=wp.int32, device=device)
            bary = wp.zeros(num_strands, dtype=wp.vec3, device=device)
            wp.launch(closest_face, dim=num_strands, device=device,
                      inputs=[mesh.id, wp.array(points[starts].astype(np.float32), dtype=wp.vec3, device=device)],
                      outputs=[face, bary])
            tri, weights = face.numpy().astype(np.int64), bary.numpy().astype(np.float64)
        else:
            tri = np.asarray(rb.triangles, dtype=np.int64).reshape(-1)
            weights = np.asarray(rb.weights, dtype=np.float64).reshape(-1, 3)
        if tri.shape != (num_strands,) or weights.shape != (num_strands, 3):
            raise ValueError(f"root binding: need one triangle and weight triple per strand ({num_strands})")
        if tri.min(initial=0) < 0 or tri.max(initial=0) >= len(rb.indices):
            raise ValueError("root binding: triangle index out of range")
        binding = {
            "triangle": arr(rb.indices[tri[order]].astype(np.int32), wp.vec3i),
            "weights": arr(weights[order].astype(ftype), vec3),
            "num_points": len(rb.points),
        }

    grid_shape = grid_cell = None
    hh = find(features, HairHair)
    if hh is not None:
        grid_cell = float(hh.cell_size)
        extent = hair_hair_extent(hh, points, counts)
        grid_shape = tuple(int(np.ceil(e / grid_cell)) + 3 for e in extent)
        if int(np.prod(grid_shape)) > hh.max_cells:
            raise ValueError(f"hair-hair grid of {grid_shape} nodes exceeds max_cells={hh.max_cells}; "
                             f"increase cell_size ({grid_cell} m) or give a smaller extent")
    return ModelFeatures(features, flags, arrays, colliders, collider_order, binding, grid_shape, grid_cell)


def hair_hair_extent(hh, points, counts) -> np.ndarray:
    """Size (3,), m, of the hair-hair grid of strands ``points`` (N, 3, world) with vertex
    ``counts``: ``hh.extent``, or the rest bounds plus twice the longest strand on each axis."""
    if hh.extent is not None:
        return np.asarray(hh.extent, dtype=np.float64).reshape(3)
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    counts = np.asarray(counts, dtype=np.int64).reshape(-1)
    if not len(points):
        return np.zeros(3)
    starts = np.concatenate([[0], np.cumsum(counts)[:-1]]).astype(np.int64)
    seg = np.zeros(len(points))
    seg[1:] = np.linalg.norm(np.diff(points, axis=0), axis=1)
    seg[starts] = 0.0
    longest = float(np.add.reduceat(seg, starts).max())
    return points.max(0) - points.min(0) + 2.0 * longest


class FeatureControl:
    """Per-frame animated data of the features (``control.features``), device coordinates.

    Collider poses move from ``start`` to ``end`` across a frame like the roots; the current and
    previous substep's poses (``pose``, ``pose_prev``, and their inverses) are updated by each step.
    """

    def __init__(self, model, control):
        self.model = model
        self._control = control
        mf = model.feature_data
        device = model.device
        transform = transform_type(model.scalar)
        self.pose_start = self.pose_end = self.pose = self.pose_prev = None
        self._synced = False
        self.meshes = []
        self.mesh_ids = None
        if mf.colliders is not None and mf.colliders.shapes:
            rest = mf.arrays["collider_rest_pose"]
            self.pose_start, self.pose_end, self.pose, self.pose_prev = (
                wp.array(rest, dtype=transform, device=device) for _ in range(4))
            inverse = _inverse_poses(rest).astype(rest.dtype)
            self.inv_pose, self.inv_pose_prev = (wp.array(inverse, dtype=transform, device=device) for _ in range(2))
            ids = np.zeros(len(rest), dtype=np.uint64)
            lower = np.zeros((len(rest), 3))
            upper = np.zeros((len(rest), 3))
            for user_index, s in enumerate(mf.colliders.shapes):
                if s.kind == "meshes":
                    mesh = wp.Mesh(points=wp.array(s.points.astype(np.float32), dtype=wp.vec3, device=device),
                                   indices=wp.array(s.indices.reshape(-1), dtype=wp.int32, device=device))
                    self.meshes.append(mesh)
                    c = mf.collider_order[user_index]
                    ids[c] = mesh.id
                    lower[c], upper[c] = s.points.min(0), s.points.max(0)
                else:
                    self.meshes.append(None)
            self.mesh_ids = wp.array(ids, dtype=wp.uint64, device=device)
            f = numpy_type(model.precision)
            self.mesh_lower = wp.array(lower.astype(f), dtype=model.vec3, device=device)
            self.mesh_upper = wp.array(upper.astype(f), dtype=model.vec3, device=device)
        self.wind = find(mf.features, Wind)
        self.wind_velocity = self.wind_time = None
        if self.wind is not None:
            v = self.wind.at(0.0) if self.wind is not None else np.zeros(3)
            self.wind_velocity = wp.array(np.array([v, v], dtype=numpy_type(model.precision)), dtype=model.vec3,
                                          device=device)
            self.wind_time = wp.zeros(2, dtype=model.scalar, device=device)
        self._binding_points = None
        if mf.binding is not None:
            self._binding_points = [wp.zeros(mf.binding["num_points"], dtype=model.vec3, device=device)
                                    for _ in range(2)]

    # -- colliders ---------------------------------------------------------------------------------

    def set_collider_poses(self, start, end=None) -> None:
        """Poses of all colliders for this frame: (C, 7) rows ``(px, py, pz, qx, qy, qz, qw)``,
        world space, in the Colliders' order; ``end`` defaults to ``start``.

        The first call (and the first after :meth:`resync`) also places the colliders at
        ``start`` for the previous substep, so that they do not sweep from their rest pose."""
        mf = self.model.feature_data
        n = len(mf.colliders.shapes) if mf.colliders is not None else 0
        for dst, rows in ((self.pose_start, start), (self.pose_end, start if end is None else end)):
            rows = np.asarray(rows, dtype=np.float64).reshape(-1, 7).copy()
            if rows.shape[0] != n:
                raise ValueError(f"expected {n} collider poses, got {rows.shape[0]}")
            rows[:, :3] -= self.model.origin
            rows[:, 3:] /= np.linalg.norm(rows[:, 3:], axis=1, keepdims=True)
            device_rows = np.empty_like(rows)
            device_rows[mf.collider_order] = rows
            dst.assign(device_rows.astype(numpy_type(self.model.precision)))
            if dst is self.pose_start and not self._synced:
                inverse = _inverse_poses(device_rows).astype(numpy_type(self.model.precision))
                for a, v in ((self.pose, device_rows), (self.pose_prev, device_rows), (self.inv_pose, inverse),
                             (self.inv_pose_prev, inverse)):
                    a.assign(v.astype(numpy_type(self.model.precision)))
        self._synced = True

    def resync(self) -> None:
        """Forget the colliders' previous pose (after restoring a saved state): the next
        :meth:`set_collider_poses` places them at its start without sweeping."""
        self._synced = False

    def set_mesh_points(self, index: int, points) -> None:
        """New local points (P, 3) of mesh collider ``index`` (Colliders order), from now on."""
        mesh = self.meshes[index]
        if mesh is None:
            raise ValueError(f"collider {index} is not a mesh")
        pts = np.asarray(points, dtype=np.float32).reshape(-1, 3)
        if pts.shape[0] != mesh.points.shape[0]:
            raise ValueError(f"mesh collider {index}: expected {mesh.points.shape[0]} points, got {pts.shape[0]}")
        mesh.points.assign(pts)
        mesh.refit()
        c = int(self.model.feature_data.collider_order[index])
        f = numpy_type(self.model.precision)
        lower, upper = self.mesh_lower.numpy(), self.mesh_upper.numpy()
        lower[c], upper[c] = pts.min(0).astype(f), pts.max(0).astype(f)
        self.mesh_lower.assign(lower)
        self.mesh_upper.assign(upper)

    # -- wind ----------------------------------------------------------------------------------------

    def set_frame_time(self, start: float, end: float) -> None:
        """The frame spans ``start`` -> ``end`` seconds: wind velocity from its keyframes, noise time."""
        if self.wind is None:
            return
        f = numpy_type(self.model.precision)
        self.wind_velocity.assign(np.array([self.wind.at(start), self.wind.at(end)], dtype=f))
        self.wind_time.assign(np.array([start, end], dtype=f))

    def set_wind(self, start, end=None) -> None:
        """Wind velocity (3,) m/s at frame start and end (overrides the keyframes for this frame)."""
        f = numpy_type(self.model.precision)
        start = np.asarray(start, dtype=np.float64).reshape(3)
        end = start if end is None else np.asarray(end, dtype=np.float64).reshape(3)
        self.wind_velocity.assign(np.array([start, end], dtype=f))

    # -- roots on a deforming mesh -----------------------------------------------------------------

    def set_binding_points(self, start, end=None) -> None:
        """World points (P, 3) of the root-binding mesh at frame start and end: sets the root targets."""
        m = self.model
        b = m.feature_data.binding
        if b is None:
            raise ValueError("the model has no RootBinding feature")
        f = numpy_type(m.precision)
        for dst, pts in zip(self._binding_points, (start, start if end is None else end)):
            pts = np.asarray(pts, dtype=np.float64).reshape(-1, 3)
            if pts.shape[0] != b["num_points"]:
                raise ValueError(f"root binding mesh: expected {b['num_points']} points, got {pts.shape[0]}")
            dst.assign((pts - m.origin).astype(f))
        c = self._control
        wp.launch(bind_roots_kernel(m.scalar), dim=m.num_strands, device=m.device,
                  inputs=[b["triangle"], b["weights"], *self._binding_points], outputs=[c.root_start, c.root_end])


class FeatureStep:
    """One featured step: collider poses, hair-hair grid, then the specialized sweep."""

    def __init__(self, model, kernel):
        self.model = model
        self.kernel = kernel
        mf = model.feature_data
        self.flags = mf.flags
        self._structs = {}
        self.grid = None
        if "hair_hair" in self.flags:
            shape = mf.grid_shape
            self.grid = {
                "lower": wp.zeros(3, dtype=model.scalar, device=model.device),
                "density": wp.zeros(shape, dtype=model.scalar, device=model.device),
                "momentum": wp.zeros(shape, dtype=model.vec3, device=model.device),
            }

    def kernels(self):
        """Every kernel a step launches (to load before a CUDA graph capture)."""
        ks = [self.kernel]
        if self.model.feature_data.colliders is not None:
            ks.append(collider_pose_kernel(self.model.scalar))
        if self.grid is not None:
            ks += [grid_reset_kernel(self.model.scalar), grid_bounds_kernel(self.model.scalar),
                   grid_splat_kernel(self.model.scalar)]
        return ks

    def _struct(self, control):
        key = id(control)
        cached = self._structs.get(key)
        if cached is not None and cached[0] is control:
            return cached[1]
        m = self.model
        mf = m.feature_data
        a = mf.arrays
        fc = control.features
        st = feature_struct(m.scalar, self.flags)()
        flags = self.flags
        if flags & set(SHAPE_KINDS):
            st.particle_radius = a["particle_radius"]
            st.collider_pose = fc.pose
            st.collider_inv_pose = fc.inv_pose
            st.collider_inv_pose_prev = fc.inv_pose_prev
            st.collider_size = a["collider_size"]
            st.collider_axis = a["collider_axis"]
            st.collider_friction = a["collider_friction"]
            st.collider_iterations = int(mf.colliders.iterations)
            for kind in SHAPE_KINDS:
                if kind in flags:
                    b, e = a["collider_ranges"][kind]
                    setattr(st, f"{kind}_begin", b)
                    setattr(st, f"{kind}_end", e)
            if "meshes" in flags:
                st.collider_mesh = fc.mesh_ids
                st.collider_depth_band = a["collider_depth_band"]
                st.collider_lower = fc.mesh_lower
                st.collider_upper = fc.mesh_upper
        if "drag" in flags:
            st.drag = a["drag"]
        if "wind" in flags:
            st.wind_velocity = fc.wind_velocity
        if "wind_noise" in flags:
            w = fc.wind
            st.wind_time = fc.wind_time
            st.noise_amplitude = float(w.noise_amplitude)
            st.noise_inv_scale = 1.0 / float(w.noise_scale)
            st.noise_frequency = float(w.noise_frequency)
            st.noise_seed = int(w.seed)
        if "hair_hair" in flags:
            hh = find(mf.features, HairHair)
            g = self.grid
            st.grid_lower = g["lower"]
            st.grid_h = mf.grid_cell
            st.grid_inv_h = 1.0 / mf.grid_cell
            st.grid_nx, st.grid_ny, st.grid_nz = mf.grid_shape
            st.grid_density = g["density"]
            st.grid_momentum = g["momentum"]
            st.grid_friction = float(hh.friction)
            st.grid_repulsion = float(hh.repulsion)
        if "shape" in flags:
            st.shape_stiffness = a["shape_stiffness"]
            st.shape_rest_frame = a["shape_rest_frame"]
            st.shape_rest_dir = a["shape_rest_dir"]
        self._structs[key] = (control, st)
        return st

    def launch(self, state_in, state_out, control, dt, root_alpha, head_inputs):
        self.pose_and_bounds(state_in, control, root_alpha)
        self.splat(state_in)
        self.sweep(state_in, state_out, control, head_inputs)

    # the phases of :meth:`launch`; a split groom (dftl_warp.simulation.multi_device) combines its parts'
    # grids between them

    def pose_and_bounds(self, state_in, control, root_alpha) -> None:
        """This substep's collider poses; the grid's lower corner from this model's particles."""
        m = self.model
        device = m.device
        if control.features is None:
            raise ValueError("this control was made before the model had features; use model.control()")
        fc = control.features
        if fc.pose is not None:
            wp.launch(collider_pose_kernel(m.scalar), dim=fc.pose.shape[0], device=device,
                      inputs=[fc.pose_start, fc.pose_end, root_alpha], outputs=[fc.pose, fc.pose_prev, fc.inv_pose, fc.inv_pose_prev])
        if self.grid is not None:
            g = self.grid
            wp.launch(grid_reset_kernel(m.scalar), dim=1, device=device, outputs=[g["lower"]])
            wp.launch(grid_bounds_kernel(m.scalar), dim=m.num_slots, device=device,
                      inputs=[state_in.positions], outputs=[g["lower"]])

    def splat(self, state_in) -> None:
        """Density and momentum of this model's particles onto the grid (from ``lower``)."""
        if self.grid is None:
            return
        m = self.model
        g = self.grid
        mf = m.feature_data
        g["density"].zero_()
        g["momentum"].zero_()
        wp.launch(grid_splat_kernel(m.scalar), dim=m.num_slots, device=m.device,
                  inputs=[state_in.positions, state_in.velocities, g["lower"], 1.0 / mf.grid_cell, *mf.grid_shape],
                  outputs=[g["density"], g["momentum"]])

    def sweep(self, state_in, state_out, control, head_inputs) -> None:
        """The featured sweep of every strand (reading the grid, if any)."""
        st = self._struct(control)
        wp.launch(self.kernel, dim=self.model.num_strands, device=self.model.device,
                  inputs=[*head_inputs, st, state_in.positions, state_in.velocities, state_in.corrections],
                  outputs=[state_out.positions, state_out.velocities, state_out.corrections])


def memory_estimate(model, correction: str = "prior") -> dict:
    """Device bytes the simulation of ``model`` holds: per strand (mean, strands of the model's
    sizes), split into the bare solver's and the features', plus fixed-size feature memory.

    Counts the State (positions, velocities, and corrections in the prior form), the Model's
    rest lengths and strand tables, the Control's root targets, and the features' arrays.
    """
    f = np.dtype(model.precision).itemsize
    points = model.num_points
    strands = max(model.num_strands, 1)
    vectors = 3 if correction == "prior" else 2
    bare = points * (vectors * 3 * f + f) + model.num_strands * (3 * 4 + 3 * 3 * f)
    mf = model.feature_data
    feature = 0
    fixed = 0
    if mf is not None:
        feature = points * mf.bytes_per_particle(model.precision) + model.num_strands * mf.bytes_per_strand(
            model.precision)
        fixed = mf.grid_bytes(model.precision)
        if mf.colliders is not None:
            shapes = mf.colliders.shapes
            fixed += len(shapes) * (6 * 7 * f + 4 * 3 * f + 2 * f + 8)
            fixed += sum(s.points.size * 4 + s.indices.size * 4 for s in shapes if s.kind == "meshes") * 2
    return {
        "bare_bytes_per_strand": bare / strands,
        "feature_bytes_per_strand": feature / strands,
        "bytes_per_strand": (bare + feature) / strands,
        "fixed_feature_bytes": fixed,
    }
