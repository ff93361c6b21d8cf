"""What the renderer draws, in world space and numpy: strands, gprims, one triangle mesh.

A :class:`RenderScene` is built from a USD stage (:mod:`.usd_scene`) or directly from numpy
arrays (:meth:`RenderScene.from_strands`). Lengths are in stage units (metres for the
simulator's output); colours are linear RGB in 0..1.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..core.bounds import box
from ..errors import plural
from ..core.layout import strand_offsets
from ..core.model import check_strand_arrays
from .camera import checked_matrix, checked_up_axis

#: default linear hair colour at the root and at the tip (a mid brown)
DEFAULT_ROOT_COLOR = (0.045, 0.022, 0.010)
DEFAULT_TIP_COLOR = (0.30, 0.17, 0.085)
#: a constant or per-strand colour is darkened towards the root by this factor
ROOT_DARKENING = 0.55

SPHERE, CAPSULE, BOX = 0, 1, 2
SHAPE_KINDS = {SPHERE: "sphere", CAPSULE: "capsule", BOX: "box"}


@dataclass
class Shape:
    """An analytic gprim. ``world_from_local``: 4x4, column vectors (``p_w = M @ [p, 1]``).

    params: sphere ``(radius, 0, 0)``; capsule ``(radius, half height of the cylinder part,
    axis 0/1/2 for X/Y/Z)``; box ``(half extents)``.
    """

    kind: int
    world_from_local: np.ndarray
    params: tuple
    path: str = ""

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """World box of the shape (the transformed local box's corners)."""
        if self.kind == SPHERE:
            half = np.full(3, self.params[0])
        elif self.kind == CAPSULE:
            half = np.full(3, self.params[0])
            half[int(self.params[2])] += self.params[1]
        else:
            half = np.asarray(self.params, dtype=np.float64)
        corners = np.array([[sx, sy, sz, 1.0] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])
        corners[:, :3] *= half
        w = corners @ np.asarray(self.world_from_local).T
        return w[:, :3].min(axis=0), w[:, :3].max(axis=0)


@dataclass
class RenderScene:
    """Everything a frame draws.

    - ``points`` (N, 3), ``curve_vertex_counts`` (S,): linear strands, root first;
    - ``radii`` (N,): tube radius at every vertex (half the USD width);
    - ``colors`` (N, 3): linear RGB per vertex;
    - ``shapes``: spheres, capsules and boxes; ``mesh_points`` (M, 3) + ``mesh_triangles``
      (K, 3): all meshes merged, in world space;
    - ``up_axis``: "Y" or "Z" (for automatic framing and turntables).
    """

    points: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    curve_vertex_counts: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    radii: np.ndarray = field(default_factory=lambda: np.zeros(0))
    colors: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    shapes: list = field(default_factory=list)
    mesh_points: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    mesh_triangles: np.ndarray = field(default_factory=lambda: np.zeros((0, 3), dtype=np.int64))
    up_axis: str = "Y"

    @classmethod
    def from_strands(cls, points, counts, widths=None, colors=None, **kw) -> "RenderScene":
        """Strands from numpy: ``points`` (N, 3); ``counts`` (S,); ``widths`` (diameters): a
        scalar, (S,) per strand or (N,) per vertex; ``colors``: None (default ramp), an RGB, (S, 3)
        or (N, 3). Bad arrays (counts that do not sum to N, a negative count, a non-finite point,
        a negative or non-finite width, widths or colours of another length) raise ValueError
        naming the first bad index, with the messages of :meth:`dftl_warp.Model.from_strands`;
        so do bad ``shapes``, ``mesh_points``, ``mesh_triangles`` or ``up_axis``
        (:meth:`check_geometry`)."""
        points, counts = check_strands(points, counts)
        n = len(points)
        if widths is None:
            widths = default_width(points)
        w = _float_array(widths, "widths").reshape(-1)
        if w.size == 1:
            w = np.full(n, w[0])
        elif w.size == len(counts) and w.size != n:
            w = np.repeat(w, counts)
        elif w.size != n:
            raise ValueError(f"{w.size} widths for {plural(len(counts), 'strand')} of {n} points: expected one, "
                             f"one per strand or one per point")
        _check_values(w, "widths", nonnegative=True)
        if colors is not None:
            c = _float_array(colors, "colors")
            if c.size % 3:
                raise ValueError(f"colors of shape {c.shape}: expected an RGB, (S, 3) or (N, 3)")
            _check_values(c.reshape(-1, 3), "colors")
        scene = cls(points=points, curve_vertex_counts=counts, radii=0.5 * w,
                    colors=strand_colors(counts, colors), **kw)
        scene.check_geometry()
        return scene

    def check(self) -> None:
        """ValueError unless the strand arrays fit together (the renderer's kernels index them
        by ``curve_vertex_counts``): counts not negative and summing to the points, finite points,
        one finite, non-negative radius and one finite colour per point; and
        :meth:`check_geometry`."""
        check_strands(self.points, self.curve_vertex_counts)
        n = len(np.asarray(self.points).reshape(-1, 3))
        radii = np.asarray(self.radii, dtype=np.float64).reshape(-1)
        colors = np.asarray(self.colors, dtype=np.float64)
        if radii.size != n:
            raise ValueError(f"{radii.size} radii for {n} points: expected one per point")
        if colors.size != 3 * n:
            raise ValueError(f"colors of shape {colors.shape} for {n} points: expected ({n}, 3)")
        _check_values(radii, "radii", nonnegative=True)
        _check_values(colors.reshape(-1, 3), "colors")
        self.check_geometry()

    def check_geometry(self) -> None:
        """ValueError naming the first bad index unless ``shapes``, the mesh and ``up_axis`` are
        fit to draw (:func:`check_shapes`, :func:`check_mesh`, "Y" or "Z"). A mesh index out of
        range crashed the renderer or read other memory; a NaN point or size blanked the image."""
        checked_up_axis(self.up_axis)
        check_shapes(self.shapes)
        check_mesh(self.mesh_points, self.mesh_triangles)

    @property
    def strand_count(self) -> int:
        return int(len(self.curve_vertex_counts))

    @property
    def segment_count(self) -> int:
        return int(np.maximum(self.curve_vertex_counts - 1, 0).sum())

    def hair_bounds(self):
        """(lo, hi) of the strand tubes, or None without strands."""
        if len(self.points) == 0:
            return None
        r = self.radii[:, None]
        return box(self.points - r)[0], box(self.points + r)[1]

    def bounds(self):
        """(lo, hi) of everything drawn, or None for an empty scene."""
        boxes = []
        hb = self.hair_bounds()
        if hb is not None:
            boxes.append(hb)
        boxes += [s.bounds() for s in self.shapes]
        if len(self.mesh_points):
            boxes.append(box(self.mesh_points))
        if not boxes:
            return None
        return np.min([b[0] for b in boxes], axis=0), np.max([b[1] for b in boxes], axis=0)

    def is_empty(self) -> bool:
        return self.segment_count == 0 and not self.shapes and len(self.mesh_triangles) == 0


def check_strands(points, counts) -> tuple[np.ndarray, np.ndarray]:
    """(points (N, 3) float64, counts (S,) int64) checked as :meth:`dftl_warp.Model.from_strands`
    checks them (:func:`~dftl_warp.core.model.check_strand_arrays`, same messages), except that a
    strand may have 0 vertices (it draws nothing)."""
    points = _float_array(points, "points")
    raw = np.asarray(counts).reshape(-1)
    if raw.size and not (np.issubdtype(raw.dtype, np.integer)
                         or (np.issubdtype(raw.dtype, np.floating) and np.all(np.mod(raw, 1) == 0))):
        raise ValueError("counts must be a 1-D array of integers (vertices per strand)")
    return check_strand_arrays(points, raw, least=0)


def check_shapes(shapes) -> None:
    """ValueError naming ``shapes[i]`` unless each is a :class:`Shape` of a known kind with a 4x4
    matrix of finite numbers and 3 finite params: a non-negative sphere radius, a non-negative
    capsule radius and an axis 0, 1 or 2, non-negative box half extents."""
    if not isinstance(shapes, (list, tuple)):
        raise ValueError(f"shapes must be a list of Shape, got {type(shapes).__name__}")
    for i, shape in enumerate(shapes):
        where = f"shapes[{i}]"
        if not isinstance(shape, Shape):
            raise ValueError(f"{where} must be a Shape, got {type(shape).__name__}")
        kind = shape.kind
        if isinstance(kind, (bool, np.bool_)) or not isinstance(kind, (int, np.integer)) or int(kind) not in SHAPE_KINDS:
            raise ValueError(f"{where} kind {kind!r}: must be 0 (sphere), 1 (capsule) or 2 (box)")
        checked_matrix(shape.world_from_local, f"{where} world_from_local", ValueError)
        p = _float_array(shape.params, f"{where} params").reshape(-1)
        if p.size != 3:
            raise ValueError(f"{where} params of {p.size} numbers: expected 3")
        for j in range(3):
            if not np.isfinite(p[j]):
                raise ValueError(f"{where} params[{j}] = {p[j]:g}: not finite")
        # a capsule's half height is not checked: the USD reader passes a negative height on
        sizes = 3 if kind == BOX else 1
        for j in range(sizes):
            if p[j] < 0:
                raise ValueError(f"{where} params[{j}] = {p[j]:g}: a {SHAPE_KINDS[int(kind)]} size must be >= 0")
        if kind == CAPSULE and p[2] not in (0.0, 1.0, 2.0):
            raise ValueError(f"{where} params[2] = {p[2]:g}: a capsule axis must be 0, 1 or 2 (X, Y, Z)")


def check_mesh(mesh_points, mesh_triangles) -> None:
    """ValueError unless ``mesh_points`` are (M, 3) finite numbers and ``mesh_triangles`` (K, 3)
    whole numbers in 0..M-1, naming the first bad row or index."""
    pts = _float_array(mesh_points, "mesh_points")
    if pts.size % 3 or (pts.size and pts.ndim != 2):
        raise ValueError(f"mesh_points of shape {pts.shape}: expected (M, 3)")
    pts = pts.reshape(-1, 3)
    _check_values(pts, "mesh_points")
    tris = np.asarray(mesh_triangles)
    if tris.size == 0:
        return
    if not (np.issubdtype(tris.dtype, np.integer)
            or (np.issubdtype(tris.dtype, np.floating) and np.all(np.mod(tris, 1) == 0))):
        raise ValueError("mesh_triangles must be whole numbers (indices into mesh_points)")
    if tris.ndim != 2 or tris.shape[1] != 3:
        raise ValueError(f"mesh_triangles of shape {tris.shape}: expected (K, 3)")
    bad = np.argwhere((tris < 0) | (tris >= len(pts)))
    if len(bad):
        k, j = (int(v) for v in bad[0])
        raise ValueError(f"mesh_triangles[{k}][{j}] = {int(tris[k, j])}: out of range for "
                         f"{plural(len(pts), 'mesh_point')}")


def _float_array(values, name: str) -> np.ndarray:
    try:
        return np.asarray(values, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be numbers") from None


def _check_values(values: np.ndarray, name: str, nonnegative: bool = False) -> None:
    """ValueError naming the first non-finite (or, ``nonnegative``, negative) row of ``values``."""
    if values.size == 0:
        return
    rows = values.reshape(len(values), -1) if values.ndim else values.reshape(1, 1)
    bad = ~np.isfinite(rows).all(axis=1)
    if bad.any():
        raise ValueError(f"{name}[{int(np.flatnonzero(bad)[0])}] is not finite")
    if nonnegative and (rows < 0).any():
        raise ValueError(f"{name}[{int(np.flatnonzero((rows < 0).any(axis=1))[0])}] is negative")


def default_width(points: np.ndarray) -> float:
    """Width used when none is authored: 1/1000 of the strands' bounding-box diagonal."""
    if len(points) == 0:
        return 0.0
    lo, hi = box(points)
    diag = float(np.linalg.norm(hi - lo))
    return max(diag * 1.0e-3, 1.0e-6)


def strand_colors(counts, colors=None) -> np.ndarray:
    """Per-vertex linear colours: a root-to-tip ramp from the default browns (``colors`` None),
    a darkened-root ramp of one RGB or of one RGB per strand, or per-vertex colours as given."""
    counts = np.asarray(counts, dtype=np.int64)
    n = int(counts.sum())
    u = root_to_tip(counts)[:, None]
    if colors is None:
        return (1.0 - u) * np.asarray(DEFAULT_ROOT_COLOR) + u * np.asarray(DEFAULT_TIP_COLOR)
    c = np.asarray(colors, dtype=np.float64).reshape(-1, 3)
    if len(c) == n and (len(c) != len(counts) or n == len(counts)):
        return c.copy()
    if len(c) == 1:
        c = np.repeat(c, n, axis=0)
    elif len(c) == len(counts):
        c = np.repeat(c, counts, axis=0)
    else:
        raise ValueError(f"{len(c)} colours for {plural(len(counts), 'strand')} of {n} vertices")
    return c * (ROOT_DARKENING + (1.0 - ROOT_DARKENING) * u)


def root_to_tip(counts) -> np.ndarray:
    """Parameter 0 (root) .. 1 (tip) of every vertex of concatenated strands."""
    counts = np.asarray(counts, dtype=np.int64)
    n = int(counts.sum())
    starts = np.repeat(strand_offsets(counts), counts)
    i = np.arange(n) - starts
    denom = np.repeat(np.maximum(counts - 1, 1), counts)
    return i / denom
