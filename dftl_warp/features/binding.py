"""Roots on a deforming triangle mesh (:class:`RootBinding`).

Model data: each device strand's triangle (three point indices) and barycentric weights.
Control (:class:`BindingControl`): the mesh's points at frame start and end (m, device
coordinates); :meth:`BindingControl.bound_roots` returns the roots they place, and the caller sets
them as the Control's root targets (:meth:`dftl_warp.core.state.Control.bind_roots`): the feature
never writes the Control. With the mesh points' velocities (:meth:`BindingControl.bound_velocities`)
the roots follow the Control's C1 path inside a frame. For the elastic solver,
:meth:`BindingControl.bound_clamps` turns each strand's clamp ghost with its triangle's frame (edge
0 and the normal) from the rest mesh (``ElasticSolver.bind_clamps``). USD: ``dftl:rootMesh`` on a
curves prim (closest point at rest). Costs one small kernel per frame (``kernels/features/binding.py``;
two more with velocities: the same sums of them, then the path's deviations; one more for elastic
clamps), nothing per step.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np
import warp as wp

from ..core.layout import strand_offsets
from ..core.precision import numpy_type
from ..errors import plural
from ..kernels.features.binding import bind_clamps_kernel, bind_roots_kernel, closest_face
from .base import finite_rows

#: name -> (type, where: "scene", "curves" or "both", description)
ATTRIBUTES = {
    "dftl:rootMesh": ("rel", "curves", "a Mesh prim the roots are bound to (closest point at rest); follows its animated points"),
}


#: how far given barycentric weights may fall below 0 or their sum stray from 1
BARYCENTRIC_TOLERANCE = 1.0e-6


@dataclass(frozen=True, eq=False)
class RootBinding:
    """Roots bound to a deforming triangle mesh: each root is a barycentric point on a triangle.

    ``points`` (P, 3) world rest positions (m), ``indices`` (T, 3). ``triangles`` (S,) and
    ``weights`` (S, 3) per input strand, or ``None`` to bind each root to the closest point of
    the rest mesh; given weights must be barycentric (each >= 0, summing to 1 within 1e-6).
    Non-finite points or weights are refused. Animate with ``control.bind_roots(start, end)`` (the mesh's world points).
    Costs nothing per step: the root targets are computed once per frame.
    """

    points: np.ndarray
    indices: np.ndarray
    triangles: np.ndarray | None = None
    weights: np.ndarray | None = None

    def __post_init__(self):
        pts = finite_rows(self.points, 3, "root binding mesh points")
        idx = np.asarray(self.indices)
        if idx.size and not np.issubdtype(idx.dtype, np.integer):
            raise ValueError(f"root binding mesh: indices must be integers, got dtype {idx.dtype}")
        if idx.size % 3:
            raise ValueError(f"root binding mesh: indices must be (T, 3) or a multiple of 3, got shape {idx.shape}")
        idx = idx.astype(np.int64).reshape(-1, 3)
        if idx.size == 0 or idx.min() < 0 or idx.max() >= len(pts):
            raise ValueError("root binding mesh: indices must reference its points")
        object.__setattr__(self, "points", pts)
        object.__setattr__(self, "indices", idx.astype(np.int32))
        if (self.triangles is None) != (self.weights is None):
            raise ValueError("root binding: give both triangles and weights, or neither")
        if self.triangles is not None:
            tri = np.asarray(self.triangles)
            if tri.size and not np.issubdtype(tri.dtype, np.integer):
                raise ValueError(f"root binding: triangles must be integers, got dtype {tri.dtype}")
            tri = tri.astype(np.int64).reshape(-1)
            bad = np.flatnonzero((tri < 0) | (tri >= len(idx)))
            if bad.size:
                raise ValueError(f"root binding: triangles[{int(bad[0])}] = {int(tri[bad[0]])} is out of range "
                                 f"0..{len(idx) - 1}")
            w = finite_rows(self.weights, 3, "root binding weights")
            bad = np.flatnonzero(np.any(w < -BARYCENTRIC_TOLERANCE, axis=1)
                                 | (np.abs(w.sum(axis=1) - 1.0) > BARYCENTRIC_TOLERANCE))
            if bad.size:
                raise ValueError(f"root binding weights row {int(bad[0])} = {w[bad[0]].tolist()} is not barycentric "
                                 "(each weight >= 0, summing to 1)")

    flags = frozenset()


def build(rb: RootBinding, ctx) -> dict:
    """``triangle`` (point indices) and barycentric ``weights`` per device strand, and the mesh's
    ``num_points``, of a model being built (``ctx``: the model's fields)."""
    device, counts, points = ctx["device"], ctx["counts"], ctx["points"]
    num_strands = len(counts)
    order = ctx["layout"].strand_order
    if rb.triangles is None:
        starts = strand_offsets(counts)
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
    if tri.min(initial=0) < 0 and rb.triangles is None:
        k = int(np.flatnonzero(tri < 0)[0])
        raise ValueError(f"root binding: no non-degenerate triangle to bind strand {k}'s root to (the closest-point "
                         f"query found none among the mesh's {len(rb.indices)} triangles)")
    if tri.min(initial=0) < 0 or tri.max(initial=0) >= len(rb.indices):
        raise ValueError("root binding: triangle index out of range")
    corners = rb.points[rb.indices[tri]]                                   # (S, 3 corners, 3)
    edge = corners[:, 1] - corners[:, 0]
    area = np.linalg.norm(np.cross(edge, corners[:, 2] - corners[:, 0]), axis=1)
    return {
        "triangle": wp.array(np.ascontiguousarray(rb.indices[tri[order]].astype(np.int32)), dtype=wp.vec3i,
                             device=device),
        "weights": wp.array(np.ascontiguousarray(weights[order].astype(ctx["ftype"])), dtype=ctx["vec3"],
                            device=device),
        "num_points": len(rb.points),
        #: the rest mesh (device coordinates), whose triangles' frames the elastic clamps turn from
        "rest_points": wp.array((rb.points - ctx["origin"]).astype(ctx["ftype"]), dtype=ctx["vec3"], device=device),
        #: strands bound to a triangle without a frame at rest (zero edge 0 or zero area)
        "degenerate": int(np.count_nonzero((np.linalg.norm(edge, axis=1) == 0) | (area == 0))),
    }


class BindingControl:
    """The binding mesh's points at frame start and end, and the roots they place (and, for the
    roots' C1 path, the points' velocities and the roots' velocities they give)."""

    def __init__(self, model, binding: dict):
        self.model = model
        self.binding = binding
        self.points = [wp.zeros(binding["num_points"], dtype=model.vec3, device=model.device) for _ in range(2)]
        self.roots = [wp.zeros(model.num_strands, dtype=model.vec3, device=model.device) for _ in range(2)]
        #: the mesh points' and the bound roots' velocities at frame start and end (made on first use)
        self.velocities = self.root_velocities = None
        #: whether the roots were bound this frame (:meth:`bound_roots`) and with velocities
        self.bound = self.moving = False
        self._warned_degenerate = False

    def bound_roots(self, start, end=None) -> tuple:
        """The roots (device strand order, m relative to ``model.origin``; Warp arrays reused by
        the next call) at frame start and end, from the mesh's world points (P, 3) then."""
        m, b = self.model, self.binding
        f = numpy_type(m.precision)
        for label, dst, pts in zip(("start", "end"), self.points, (start, start if end is None else end)):
            pts = finite_rows(pts, 3, f"root binding mesh points ({label})")
            if pts.shape[0] != b["num_points"]:
                raise ValueError(f"root binding mesh: expected {b['num_points']} points, got {pts.shape[0]}")
            dst.assign((pts - m.origin).astype(f))
        wp.launch(bind_roots_kernel(m.scalar), dim=m.num_strands, device=m.device,
                  inputs=[b["triangle"], b["weights"], *self.points], outputs=self.roots)
        self.bound, self.moving = True, False
        return self.roots[0], self.roots[1]

    def bound_velocities(self, start, end=None) -> tuple:
        """The bound roots' velocities (device strand order, units/s; Warp arrays reused by the
        next call) at frame start and end, from the mesh points' velocities (P, 3) then: the same
        barycentric sums as the roots (velocities are not shifted by the origin)."""
        m, b = self.model, self.binding
        if self.velocities is None:
            self.velocities = [wp.zeros_like(p) for p in self.points]
            self.root_velocities = [wp.zeros_like(r) for r in self.roots]
        f = numpy_type(m.precision)
        for dst, v in zip(self.velocities, (start, start if end is None else end)):
            v = np.asarray(v, dtype=np.float64).reshape(-1, 3)
            if v.shape[0] != b["num_points"] or not np.isfinite(v).all():
                raise ValueError(f"root binding mesh: expected {b['num_points']} finite point velocities, "
                                 f"got {v.shape[0]}")
            dst.assign(v.astype(f))
        wp.launch(bind_roots_kernel(m.scalar), dim=m.num_strands, device=m.device,
                  inputs=[b["triangle"], b["weights"], *self.velocities], outputs=self.root_velocities)
        self.moving = True
        return self.root_velocities[0], self.root_velocities[1]

    def bound_clamps(self, offset, frame_duration: float, ghost_start, ghost_end, deviation_start,
                     deviation_end, rotation_start, rotation_end) -> None:
        """The elastic solver's clamp ghosts of the frame last bound (:meth:`bound_roots`, device
        strand order, m relative to ``model.origin``): ``offset`` (the authored ghost minus the
        authored root, per device strand) turned by the rotation of the strand's triangle's frame
        (edge 0 and the normal) from the rest mesh, added to the bound root; with the points'
        velocities of :meth:`bound_velocities` and ``frame_duration`` (s) > 0 also the deviations of
        their C1 path (else zero: the linear path), and those rotations at the frame's start and end
        (3x3, identity where degenerate). Written into the given Warp arrays; one kernel
        (``kernels/features/binding.py: bind_clamps_kernel``). Strands bound to a degenerate
        triangle keep the authored offset (a warning says how many)."""
        m, b = self.model, self.binding
        if not self.bound:
            raise ValueError("root binding: bind the roots of the frame (control.bind_roots) before the clamps")
        if b["degenerate"] and not self._warned_degenerate:
            self._warned_degenerate = True
            warnings.warn(f"root binding: {plural(b['degenerate'], 'strand')} "
                          f"{'is' if b['degenerate'] == 1 else 'are'} "
                          "bound to triangles with no frame at rest "
                          "(zero edge 0 or zero area): their elastic clamp moves with the root without turning",
                          stacklevel=3)
        moving = self.moving and frame_duration > 0
        velocities = self.velocities if moving else self.points
        wp.launch(bind_clamps_kernel(m.scalar), dim=m.num_strands, device=m.device,
                  inputs=[b["triangle"], b["weights"], offset, b["rest_points"], *self.points, *velocities,
                          float(frame_duration) if moving else 0.0],
                  outputs=[ghost_start, ghost_end, deviation_start, deviation_end, rotation_start, rotation_end])


def from_scene(curves, frame) -> list:
    """The RootBinding of curves prims bound to one ``dftl:rootMesh`` (grouped by it), at ``frame``."""
    mesh = curves[0].root_mesh
    return [] if mesh is None else [RootBinding(mesh.world_points(frame), mesh.triangles)]


def update_from_scene(curves, control, frame, nxt, shot=None, time_codes_per_second=None) -> None:
    """Roots of an animated ``dftl:rootMesh`` for the frame ``frame`` -> ``nxt = frame + 1`` (time
    codes).

    With ``shot`` (first, last frame simulated) and ``time_codes_per_second`` the roots follow the
    C1 path (:class:`~dftl_warp.core.state.Control`): the mesh points' velocities at ``frame`` and
    ``nxt`` are central differences over the neighbouring frames (one-sided at the shot's ends,
    :func:`~dftl_warp.core.state.frame_velocity`); without them the roots move linearly."""
    mesh = curves[0].root_mesh
    if mesh is None or not mesh.animated:
        return
    start, end = mesh.world_points(frame), mesh.world_points(nxt)
    if shot is None or time_codes_per_second is None:
        control.bind_roots(start, end)
        return
    from ..core.state import frame_velocity

    duration = (nxt - frame) / float(time_codes_per_second)
    points = {frame: start, nxt: end}

    def points_at(f):
        if f not in points:
            points[f] = mesh.world_points(f)
        return points[f]

    control.bind_roots(start, end, velocity_start=frame_velocity(points_at, frame, *shot, duration),
                       velocity_end=frame_velocity(points_at, nxt, *shot, duration), frame_duration=duration)
