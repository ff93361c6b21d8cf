"""Signed distance fields of triangle-mesh colliders (docs/features.md, "Signed distance fields of
mesh colliders"): a narrow band of distances around the surface in bricks of 8^3 cells, rebuilt on
the device from the mesh whenever its points change, sampled per particle per substep; exact mesh
queries where the field cannot answer. Kernels: ``kernels/features/sdf.py``.

Which meshes get one (:func:`field_settings`): ``TriangleMesh(sdf=True)`` (USD
``dftl:collisionSdf = true``), or automatically from :data:`SDF_MIN_TRIANGLES` triangles unless
``sdf=False``. Cell size: ``sdf_cell`` (USD ``dftl:collisionSdfCellSize``), by default the mesh's
mean edge length; tolerance: ``sdf_tolerance``, by default :data:`TOLERANCE_CELLS` cells.
"""

from __future__ import annotations

import warnings

import numpy as np
import warp as wp

from ...kernels.features.sdf import (
    BRICK,
    BRICK_CELLS,
    BRICK_NODES,
    FAR_BRICK,
    SQRT3,
    TEST_SLOTS,
    WHY_EXACT,
    SdfGrid,
    cell_states_kernel,
    fill_nodes_kernel,
    mark_bricks_kernel,
    mesh_distance_kernel,
    sample_kernel,
    share_nodes_kernel,
)
from ...core.bounds import box
from .base import ColliderApproximationWarning

#: meshes of at least this many triangles collide through a field unless told otherwise
#: (docs/features.md: measured cost of the exact query against the field's)
SDF_MIN_TRIANGLES = 20_000
#: default tolerance of the field's interpolation error, in cells
TOLERANCE_CELLS = 1.0 / 16.0
#: margin of the band beyond what the reach needs, in cells
BAND_MARGIN = 0.25
#: the grid's extent beyond the rest mesh's band, as a fraction of it (room to deform)
GROWTH = 0.25
#: the most bricks one collider's grid may have (its brick map is 4 bytes per brick)
MAX_BRICKS = 1 << 26
#: device bytes per pool brick: distances (float32), gradients (3 x float16), cell states, coordinates
BYTES_PER_BRICK = BRICK_NODES * (4 + 6) + BRICK_CELLS + 12


def bounds(points) -> tuple[np.ndarray, np.ndarray]:
    """The lower and upper corners (3,), m, of ``points`` (P, 3)."""
    return box(points)


def mean_edge_length(points: np.ndarray, indices: np.ndarray) -> float:
    """Mean length (m) of the triangles' edges."""
    tri = points[indices]
    return float(np.mean(np.linalg.norm(tri - np.roll(tri, 1, axis=1), axis=2)))


def field_settings(shape) -> tuple[bool, float, float]:
    """``(uses_field, cell, tolerance)`` (m) of a :class:`~.mesh.TriangleMesh`."""
    uses = shape.sdf if shape.sdf is not None else len(shape.indices) >= SDF_MIN_TRIANGLES
    cell = shape.sdf_cell if shape.sdf_cell is not None else mean_edge_length(shape.points, shape.indices)
    tolerance = shape.sdf_tolerance if shape.sdf_tolerance is not None else TOLERANCE_CELLS * cell
    return bool(uses), float(cell), float(tolerance)


def field_band(depth_band: float, max_radius: float, cell: float) -> float:
    """Half-width (m) of the band of nodes that hold distances: a point within the contact
    distance plus ``depth_band`` of the surface has its cell's 8 corners within
    ``depth_band + max_radius + sqrt(3) cell`` (plus :data:`BAND_MARGIN` cells)."""
    return float(depth_band) + float(max_radius) + (SQRT3 + BAND_MARGIN) * float(cell)


def field_bricks(points: np.ndarray, cell: float, band: float) -> np.ndarray:
    """Bricks (3,) along each axis of the grid of a field of ``cell`` and half-width ``band`` (m)
    around the mesh ``points``: its rest bounds and band, grown by :data:`GROWTH` (whole numbers as
    floats: a tiny cell's count does not overflow)."""
    lo, hi = bounds(points)
    extent = hi - lo + 2.0 * band
    return np.ceil(extent * (1.0 + GROWTH) / (BRICK * cell)) + 2.0


class FieldTooLarge(ValueError):
    """A signed distance field of more than :data:`MAX_BRICKS` bricks (its cell too small for the mesh)."""


def check_field_size(shape, cell_name: str) -> None:
    """:class:`FieldTooLarge` when the field of the :class:`~.mesh.TriangleMesh` ``shape`` needs more
    than :data:`MAX_BRICKS` bricks for hair of radius 0 (a lower bound: the hair's radius widens the
    band), naming the cell as ``cell_name`` (``dftl:collisionSdfCellSize``); nothing when the shape
    has no field."""
    uses, cell, _ = field_settings(shape)
    if not uses:
        return
    n = float(np.prod(field_bricks(shape.points, cell, field_band(shape.depth_band, 0.0, cell))))
    if n > MAX_BRICKS:
        which = f"{cell_name} = {cell:g}" if shape.sdf_cell is not None else \
            f"the default cell ({cell:g}, the mean edge length; {cell_name} is not authored)"
        lo, hi = bounds(shape.points)
        raise FieldTooLarge(f"{which}: the signed distance field of a mesh {float(np.max(hi - lo)):g} units across "
                            f"needs {n:.4g} bricks of 8^3 cells (at most {MAX_BRICKS}): author a larger {cell_name}")


def estimated_bytes(points: np.ndarray, indices: np.ndarray, cell: float, band: float) -> int:
    """Rough device bytes of a field (before it is built): the pool of twice the bricks a band of
    half-width ``band`` around the surface's area needs, and the brick map."""
    tri = points[indices]
    area = 0.5 * float(np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1).sum())
    side = BRICK * cell
    bricks = area / side**2 * (2.0 * band / side + 2.0)
    lo, hi = bounds(points)
    extent = hi - lo + 2.0 * band
    grid = np.prod(np.ceil(extent * (1.0 + GROWTH) / side) + 2)
    return int(2.0 * bricks * BYTES_PER_BRICK + 4 * grid)


class _Field:
    """One collider's field: device index ``c``, its settings and place in the shared arrays."""

    def __init__(self, c, name, cell, band, tolerance, bricks, map_offset):
        self.c, self.name = c, name
        self.cell, self.band, self.tolerance = cell, band, tolerance
        self.bricks = np.asarray(bricks, dtype=np.int64)
        self.num_bricks = int(np.prod(self.bricks))
        self.map_offset = map_offset
        self.pool_offset = 0
        self.capacity = 0
        self.used = 0
        self.needed = 0
        self.complete = True
        self._warned = set()

    def grid(self, lo: np.ndarray, hi: np.ndarray):
        """The :class:`SdfGrid` for the mesh's current bounds ``lo``, ``hi`` (3,), m: the grid
        centred on them, on the lattice of the cell (so that a still mesh keeps its nodes)."""
        lo, hi = np.asarray(lo, dtype=np.float64), np.asarray(hi, dtype=np.float64)
        span = self.bricks * BRICK * self.cell
        origin = np.floor((0.5 * (lo + hi) - 0.5 * span) / self.cell) * self.cell
        self.complete = bool(np.all(origin <= lo - self.band) and np.all(origin + span >= hi + self.band))
        g = SdfGrid()
        g.origin = wp.vec3f(*origin.astype(np.float32))
        g.cell = float(self.cell)
        g.inv_cell = float(1.0 / self.cell)
        g.band = float(self.band)
        g.reach = float(self.band - SQRT3 * self.cell)
        g.tolerance = float(self.tolerance)
        g.bricks = wp.vec3i(*(int(b) for b in self.bricks))
        g.map_offset = int(self.map_offset)
        g.pool_offset = int(self.pool_offset)
        g.complete = int(self.complete)
        return g

    def warn(self, key: str, message: str) -> None:
        if key not in self._warned:
            self._warned.add(key)
            warnings.warn(f"{self.name or 'mesh collider'}: {message}", ColliderApproximationWarning, stacklevel=4)


class MeshFields:
    """The signed distance fields of a Control's mesh colliders, in arrays shared by all of them
    (the step struct's ``collider_sdf``, ``sdf_brick_map``, ``sdf_values``, ``sdf_cells``);
    ``entries``: ``(device index, shape, wp.Mesh)`` of the colliders that use one. Colliders
    without a field have ``cell`` 0 in ``collider_sdf``.

    The pool holds twice the bricks the rest mesh needs (64 more at least); a frame that needs
    more answers the rest by exact queries (warned once), as does a mesh deformed beyond the grid
    (its rest band grown by :data:`GROWTH`)."""

    def __init__(self, device, num_colliders: int, entries, max_radius: float):
        self.device = device
        self.fields: dict = {}
        self._grids_host = [SdfGrid() for _ in range(max(num_colliders, 1))]
        for g in self._grids_host:
            g.cell = 0.0
        map_size = 0
        plans = []
        for c, shape, mesh in entries:
            _, cell, tolerance = field_settings(shape)
            band = field_band(shape.depth_band, max_radius, cell)
            bricks = field_bricks(shape.points, cell, band)
            if float(np.prod(bricks)) > MAX_BRICKS:
                raise FieldTooLarge(f"{shape._label()}: a signed distance field of {cell:.3g} m cells needs "
                                    f"{float(np.prod(bricks)):.4g} bricks (at most {MAX_BRICKS}); give a larger sdf_cell")
            bricks = bricks.astype(np.int64)
            field = _Field(c, shape.name, cell, band, tolerance, bricks, map_size)
            map_size += field.num_bricks
            plans.append((field, shape, mesh))
        self.brick_map = wp.full(max(map_size, 1), FAR_BRICK, dtype=wp.int32, device=device)
        self._count = wp.zeros(1, dtype=wp.int32, device=device)
        # the rest mesh's bricks size the pool
        pool = 0
        for field, shape, mesh in plans:
            field.capacity = 0
            needed = self._mark(field, mesh, *bounds(shape.points), wp.empty(1, dtype=wp.vec3i, device=device))
            field.pool_offset = pool
            field.capacity = int(min(field.num_bricks, max(2 * needed, needed + 64)))
            pool += field.capacity
        self.brick_coords = wp.zeros(max(pool, 1), dtype=wp.vec3i, device=device)
        self.values = wp.zeros(max(pool, 1) * BRICK_NODES, dtype=wp.float32, device=device)
        self.gradients = wp.zeros(max(pool, 1) * BRICK_NODES, dtype=wp.vec3h, device=device)
        self.cells = wp.zeros(max(pool, 1) * BRICK_CELLS, dtype=wp.uint8, device=device)
        self.grids = wp.array(self._grids_host, dtype=SdfGrid, device=device)
        # the tests' outcomes, then the samples they took (a diagnostic: COUNT_FIELD_TESTS)
        self.test_counts = wp.zeros((len(WHY_EXACT) + 1) * TEST_SLOTS, dtype=wp.int32, device=device)
        self._meshes = {}
        for field, shape, mesh in plans:
            self.fields[field.c] = field
            self._meshes[field.c] = mesh
            self.build(field.c, *bounds(shape.points))

    @property
    def bytes(self) -> int:
        """Device bytes of the fields."""
        return int(self.brick_map.capacity + self.brick_coords.capacity + self.values.capacity
                   + self.gradients.capacity + self.cells.capacity + self.grids.capacity)

    def _mark(self, field, mesh, lo, hi, coords) -> int:
        grid = field.grid(lo, hi)
        self._grids_host[field.c] = grid
        self._count.zero_()
        wp.launch(mark_bricks_kernel, dim=field.num_bricks, device=self.device,
                  inputs=[mesh.id, grid, field.capacity, self.brick_map, coords, self._count])
        return int(self._count.numpy()[0])

    def build(self, c: int, lo, hi) -> None:
        """Rebuild the field of device collider ``c`` from its mesh (already refitted to points
        whose bounds are ``lo``, ``hi`` (3,), local, m)."""
        field, mesh = self.fields[c], self._meshes[c]
        field.needed = self._mark(field, mesh, lo, hi, self.brick_coords)
        field.used = min(field.needed, field.capacity)
        grid = self._grids_host[c]
        self.grids.assign(wp.array(self._grids_host, dtype=SdfGrid, device="cpu"))
        if field.used:
            wp.launch(fill_nodes_kernel, dim=field.used * BRICK_CELLS, device=self.device,
                      inputs=[mesh.id, grid, self.brick_coords, self.values, self.gradients])
            wp.launch(share_nodes_kernel, dim=field.used * BRICK_NODES, device=self.device,
                      inputs=[mesh.id, grid, self.brick_map, self.brick_coords, self.values, self.gradients])
            wp.launch(cell_states_kernel, dim=field.used * BRICK_CELLS, device=self.device,
                      inputs=[grid, self.values, self.gradients, self.cells])
        if field.needed > field.capacity:
            field.warn("pool", f"its signed distance field needs {field.needed} bricks, more than the "
                               f"{field.capacity} reserved at rest: the rest are answered by exact mesh queries")
        if not field.complete:
            field.warn("grid", "the mesh deformed beyond its signed distance field's grid: beyond it, "
                               "exact mesh queries answer")

    def suspend(self, c: int) -> None:
        """Device collider ``c`` collides through exact mesh queries until its field is built again
        (:meth:`build`)."""
        still = SdfGrid()
        still.cell = 0.0
        self._grids_host[c] = still
        self.grids.assign(wp.array(self._grids_host, dtype=SdfGrid, device="cpu"))

    def fill_struct(self, st) -> None:
        st.collider_sdf = self.grids
        st.sdf_brick_map = self.brick_map
        st.sdf_values = self.values
        st.sdf_cells = self.cells
        st.sdf_tests = self.test_counts

    def tests(self, reset: bool = True) -> dict:
        """How many tests of the fields ended how since the last reset: ``{WHY_EXACT entry: count}``
        (the first ``EXACT_FROM`` entries: answered by the field, after one sample, two, or a
        trace; the others went to the exact mesh query). Counted only by kernels built with
        ``kernels.features.mesh.COUNT_FIELD_TESTS`` on (a diagnostic; zeros otherwise)."""
        counts = self.test_counts.numpy().reshape(len(WHY_EXACT) + 1, TEST_SLOTS).sum(1, dtype=np.int64)
        if reset:
            self.test_counts.zero_()
        return {why: int(n) for why, n in zip(WHY_EXACT, counts)}

    def samples(self) -> int:
        """The field's samples the counted tests took since the last reset (read it before
        :meth:`tests` resets; counted as the tests are)."""
        return int(self.test_counts.numpy().reshape(len(WHY_EXACT) + 1, TEST_SLOTS)[-1].sum(dtype=np.int64))

    def sample(self, c: int, points):
        """Probe the field of device collider ``c`` at local ``points`` (N, 3), m: ``(state,
        distance, normal)`` numpy arrays (state: 0 far, 1 answers, 2 exact query needed)."""
        pts = wp.array(np.asarray(points, dtype=np.float32).reshape(-1, 3), dtype=wp.vec3f, device=self.device)
        n = pts.shape[0]
        state = wp.zeros(n, dtype=wp.int32, device=self.device)
        dist = wp.zeros(n, dtype=wp.float32, device=self.device)
        normal = wp.zeros(n, dtype=wp.vec3f, device=self.device)
        wp.launch(sample_kernel, dim=n, device=self.device,
                  inputs=[self.grids, c, self.brick_map, self.values, self.cells, pts, state, dist, normal])
        return state.numpy(), dist.numpy().astype(np.float64), normal.numpy().astype(np.float64)

    def stats(self, c: int) -> dict:
        """The field of device collider ``c`` this frame: cell (m), band (m), tolerance (m), bricks
        used / reserved / needed, and the fraction of its band cells that answer."""
        f = self.fields[c]
        used = f.used
        states = self.cells.numpy()[f.pool_offset * BRICK_CELLS:(f.pool_offset + used) * BRICK_CELLS]
        near = int(np.count_nonzero(states))
        return dict(cell=f.cell, band=f.band, tolerance=f.tolerance, bricks_used=used, bricks_reserved=f.capacity,
                    bricks_needed=f.needed, band_cells=near,
                    answering_fraction=float(np.count_nonzero(states == 1) / near) if near else 1.0)


def mesh_signed_distance(mesh: wp.Mesh, points, max_dist: float = 1.0e6):
    """Exact signed distance (m; pseudo-normal sign, negative inside) and unit gradient of ``mesh``
    at local ``points`` (N, 3); ``max_dist`` where nothing is closer."""
    device = mesh.points.device
    pts = wp.array(np.asarray(points, dtype=np.float32).reshape(-1, 3), dtype=wp.vec3f, device=device)
    dist = wp.zeros(pts.shape[0], dtype=wp.float32, device=device)
    normal = wp.zeros(pts.shape[0], dtype=wp.vec3f, device=device)
    wp.launch(mesh_distance_kernel, dim=pts.shape[0], device=device, inputs=[mesh.id, pts, float(max_dist), dist, normal])
    return dist.numpy().astype(np.float64), normal.numpy().astype(np.float64)

