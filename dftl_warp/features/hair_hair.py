"""Hair-hair interaction (:class:`HairHair`) on a grid that follows the hair (Petrovic et al. 2005).

Model data: the grid's node counts and cell size (m), and what each particle splats: its hair
volume over a cell's, relative to the groom's rest density (:func:`grid_weights`). Step scratch
(:class:`Grid`): the grid's lower corner (m), density (relative to the rest density, per node) and
momentum (relative density x m/s per node), rebuilt every
``splat_interval`` substeps (``kernels/features/grid.py``, ``grid_strands.py``). USD:
``dftl:hairHair`` and ``dftl:hairHair*`` on the scene. Memory: 4 scalars per node.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
import warp as wp

from ..core.bounds import box
from ..core.layout import strand_offsets
from ..kernels.features.grid import grid_reset_kernel, grid_splat_kernel
from ..kernels.features.grid_strands import grid_bounds_strands_kernel, grid_splat_strands_kernel
from ..core.model import DEFAULT_HAIR_WIDTH
from .base import authored, find, nonnegative, positive, vector

#: default repulsion (m/s^2 per unit relative density across a cell): the hair at a groom's edge at
#: rest is pushed out at about half of g
DEFAULT_REPULSION = 5.0

#: name -> (type, where: "scene", "curves" or "both", description)
ATTRIBUTES = {
    "dftl:hairHair": (bool, "scene", "true turns hair-hair interaction on"),
    "dftl:hairHairCellSize": (float, "scene", "grid cell size (stage units); default 4 x the mean segment length"),
    "dftl:hairHairFriction": (float, "scene", "rate (1/s) of relaxation toward the local mean velocity"),
    "dftl:hairHairRepulsion": (float, "scene", "acceleration (stage units/s^2) per unit difference of the hair's "
                               "density relative to its rest density, across a cell"),
    "dftl:hairHairSplatInterval": (int, "scene", "substeps between rebuilds of the grid (1: every substep)"),
    "dftl:hairHairThreshold": (float, "scene", "relative density below which the hair exerts no repulsion; default "
                               "the densest node at rest (info prints it): a groom at rest is not pushed. 0: all of it"),
}

#: CUDA threads per block of the per-strand splat: 160 registers a thread, so one block of 256 per
#: multiprocessor (8 warps) or three of 128 (12 warps); H200, 1M production scene: 8.47 -> 7.59 ms
#: (docs/benchmarks.md; ``scripts/profile_features.py --block-dims`` measures others)
SPLAT_BLOCK_DIM = 128

#: how the grid is splatted: "particles" (one thread per particle, one atomic per node and particle)
#: or "strands" (one thread per strand, a strand's runs through one cell summed first)
SPLATS = ("particles", "strands")


@dataclass(frozen=True, eq=False)
class HairHair:
    """Hair-hair interaction on a grid of ``cell_size`` (m) that follows the hair.

    ``friction`` (1/s): rate at which velocities relax toward the grid (local volume-weighted mean)
    velocity; ``repulsion`` (m/s^2): acceleration per unit difference of the hair's *relative
    density* across one cell, pushing particles toward lower density. The relative density is the
    hair's volume fraction (hair volume per volume, from the particles' widths and Voronoi lengths)
    over its typical value at rest (``rest_density``; None: computed from the rest positions,
    :func:`rest_density`): 1 where the hair is as dense as it typically is at rest. So the push
    does not depend on how many strands or vertices represent the hair (it grew with them: 10 times
    the strands pushed 10 times harder), and hair at the edge of a groom at rest is pushed out at
    about ``repulsion`` (default :data:`DEFAULT_REPULSION`). ``threshold``: the relative density
    below which the hair exerts no repulsion, the push following ``max(rho - threshold, 0)``. None
    (the default): the densest node of the hair at rest (:func:`rest_peak`, which ``info`` prints),
    so a groom at rest is not pushed and the authored shape stays its equilibrium, while hair packed
    denser than anywhere at rest is; 0: all of the density pushes, and a groom at rest swells at its
    edges (the Bangs groom's tips lifted 3.6 mm off the head in 2 s, docs/features.md).
    ``hair_width`` (m): the diameter of hair without widths (default human hair's). ``extent``
    (3,), m: the grid's size,
    by default the rest bounds of the hair plus twice the longest strand on each axis, capped
    at ``max_cells`` nodes (particles outside the grid feel nothing).

    ``splat_interval``: the grid is rebuilt on the first substep of each frame and every
    ``splat_interval``-th substep after it (1: every substep; at least the substeps per frame:
    once per frame); in between the density alone is splatted again every substep (the
    repulsion never lags the particles), while the momentum is the last rebuild's, splatted with
    each particle ``(splat_interval - 1) dt / 2`` ahead along its velocity (centred on the
    substeps that use it). ``splat``: ``"particles"`` (one thread per particle) or ``"strands"``
    (one per strand, fewer atomics; the same sums up to rounding), see :data:`SPLATS`.
    """

    cell_size: float
    friction: float = 2.0
    repulsion: float = DEFAULT_REPULSION
    hair_width: float = DEFAULT_HAIR_WIDTH
    rest_density: float | None = None
    threshold: float | None = None
    extent: np.ndarray | None = None
    max_cells: int = 1 << 24
    splat_interval: int = 1
    #: "strands" by default: on an H200 3.6x (4 cm cells) and 1.4x (1 cm) cheaper than "particles"
    #: (docs/benchmarks.md); the same sums up to rounding
    splat: str = "strands"

    def __post_init__(self):
        try:
            cell = float(self.cell_size)
        except (TypeError, ValueError):
            cell = float("nan")
        if not (np.isfinite(cell) and cell > 0):
            raise ValueError(f"hair-hair cell_size must be a finite number > 0 (m), got {self.cell_size!r}")
        if self.extent is not None:
            extent = vector(self.extent, 3, "hair-hair extent")
            if np.any(extent <= 0):
                raise ValueError(f"hair-hair extent must be 3 finite lengths > 0 (m), got {self.extent!r}")
            object.__setattr__(self, "extent", extent)
        n = self.max_cells
        if isinstance(n, (bool, np.bool_)) or not isinstance(n, (int, np.integer)) or n < 1:
            raise ValueError(f"hair-hair max_cells must be an integer >= 1, got {n!r}")
        nonnegative(self.friction, "hair-hair friction")
        nonnegative(self.repulsion, "hair-hair repulsion")
        if self.threshold is not None:
            nonnegative(self.threshold, "hair-hair threshold")
        positive(self.hair_width, "hair-hair hair_width", "m")
        if self.rest_density is not None:
            positive(self.rest_density, "hair-hair rest_density", "volume fraction")
        k = self.splat_interval
        if isinstance(k, (bool, np.bool_)) or not isinstance(k, (int, np.integer)) or k < 1:
            raise ValueError(f"hair-hair splat_interval must be an integer >= 1 (substeps), got {k!r}")
        if self.splat not in SPLATS:
            raise ValueError(f"hair-hair splat must be one of {', '.join(SPLATS)}, got {self.splat!r}")

    flags = frozenset({"hair_hair"})


def hair_hair_extent(hh: HairHair, points, counts) -> np.ndarray:
    """Size (3,), m, of the hair-hair grid of strands ``points`` (N, 3, world) with vertex
    ``counts``: ``hh.extent``, or the rest bounds plus twice the longest strand on each axis."""
    if hh.extent is not None:
        return np.asarray(hh.extent, dtype=np.float64).reshape(3)
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    if not len(points):
        return np.zeros(3)
    starts = strand_offsets(counts)
    seg = np.zeros(len(points))
    seg[1:] = np.linalg.norm(np.diff(points, axis=0), axis=1)
    seg[starts] = 0.0
    longest = float(np.add.reduceat(seg, starts).max())
    lo, hi = box(points)
    return hi - lo + 2.0 * longest


def volume_fractions(points, counts, widths, cell: float, hair_width: float = DEFAULT_HAIR_WIDTH) -> np.ndarray:
    """Each point's hair volume over a grid cell's (dimensionless, input order): ``pi r^2 l / cell^3``,
    ``r`` half its width (``widths``: one or one per point; None or 0: ``hair_width``), ``l`` its Voronoi
    length along the strand (half of each segment it ends or starts) at ``points`` (N, 3)."""
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    starts = strand_offsets(counts)
    seg = np.zeros(len(points))
    seg[1:] = np.linalg.norm(np.diff(points, axis=0), axis=1)
    seg[starts] = 0.0  # roots end no segment
    length = 0.5 * seg
    length[:-1] += 0.5 * seg[1:]   # the segment a point starts (0 where the next point is a root)
    w = hair_width if widths is None else np.asarray(widths, dtype=np.float64).reshape(-1)
    # a width of 0 (a prim without widths simulated beside prims with them) is hair_width's hair
    w = np.where(np.asarray(w) > 0.0, w, hair_width)
    return np.pi * (0.5 * w) ** 2 * length / float(cell) ** 3


def splat_nodes(points, weights, cell: float, shape=None) -> np.ndarray:
    """Node densities (3D array from the points' lower corner) of ``weights`` splatted trilinearly
    at ``points`` (N, 3) on a grid of ``cell`` (numpy; the device kernels' weights). ``shape``: the
    device grid's node counts (:func:`grid_dimensions`); the points it leaves out (its extent is
    smaller than the hair's) are left out here too, and the array is no larger than that grid."""
    g = (np.asarray(points, dtype=np.float64).reshape(-1, 3) - box(points)[0]) / float(cell)
    base = np.floor(g).astype(np.int64)
    weights = np.broadcast_to(np.asarray(weights, dtype=np.float64).reshape(-1), len(g))
    if shape is not None:
        # the device grid's cell of a point is base + 1 (one cell of margin below), splatted where
        # that is below its last node but one (kernels/features/grid.py, grid_cell)
        inside = np.all(base < np.asarray(shape, dtype=np.int64) - 2, axis=1)
        g, base, weights = g[inside], base[inside], weights[inside]
        if not len(g):
            return np.zeros((1, 1, 1))
    f = g - base
    shape = base.max(0) + 2
    node = (base[:, 0] * shape[1] + base[:, 1]) * shape[2] + base[:, 2]
    rho = np.zeros(int(np.prod(shape)))
    for c in range(8):
        d = (c & 1, (c >> 1) & 1, (c >> 2) & 1)
        w = np.array(weights, dtype=np.float64)
        for axis in range(3):
            w *= f[:, axis] if d[axis] else 1.0 - f[:, axis]
        rho += np.bincount(node + (d[0] * shape[1] + d[1]) * shape[2] + d[2], weights=w, minlength=rho.size)
    return rho.reshape(shape)


def rest_statistics(points, fractions, cell: float, shape=None) -> tuple[float, float]:
    """(typical volume fraction, densest node relative to it) of the hair at ``points`` (N, 3), from
    one trilinear splat on a grid of ``cell`` (m): the typical value is ``sum rho^2 / sum rho`` over
    the nodes (the density a particle sits in; 1 where there is no hair volume), and a
    ``threshold`` at least the densest node leaves the hair at rest without repulsion (0 where there
    is no hair volume). ``shape``: the device grid's node counts (only the hair inside it counts;
    see :func:`splat_nodes`)."""
    fractions = np.asarray(fractions, dtype=np.float64).reshape(-1)
    if not len(fractions) or fractions.sum() <= 0.0:
        return 1.0, 0.0
    rho = splat_nodes(points, fractions, cell, shape)
    total = np.sum(rho)
    if total <= 0.0:
        return 1.0, 0.0
    typical = float(np.sum(rho ** 2) / total)
    return typical, float(rho.max()) / typical


def rest_density(points, fractions, cell: float, shape=None) -> float:
    """The hair's typical volume fraction at ``points`` (:func:`rest_statistics`)."""
    return rest_statistics(points, fractions, cell, shape)[0]


def rest_peak(points, fractions, cell: float, shape=None) -> float:
    """The densest node of the hair at ``points`` relative to its :func:`rest_density`
    (:func:`rest_statistics`)."""
    return rest_statistics(points, fractions, cell, shape)[1]


def group_rest_statistics(hh: HairHair, points, counts, widths) -> tuple[float, float]:
    """:func:`rest_statistics` of strands ``points`` (N, 3) / ``counts`` with ``widths`` (one, one
    per point or None) on ``hh``'s grid (:func:`grid_dimensions`: a ValueError where it has too many
    nodes, before any is allocated): what the parts of a groom split across devices share."""
    shape, cell = grid_dimensions(hh, points, counts)
    return rest_statistics(points, volume_fractions(points, counts, widths, cell, hh.hair_width), cell, shape)


def resolved(hh: HairHair, typical: float, peak: float) -> tuple[float, float]:
    """(rest density, threshold) of ``hh`` for hair whose rest statistics are ``typical`` and
    ``peak`` (:func:`rest_statistics`): ``hh``'s own where given, else the typical volume fraction
    and the densest node, that node relative to the rest density used."""
    rest = typical if hh.rest_density is None else hh.rest_density
    return rest, (peak * typical / rest if hh.threshold is None else hh.threshold)


def with_rest_density(features, points, counts, widths) -> tuple[list, float | None]:
    """``features`` with their :class:`HairHair` (if any, and without one) given the rest density of
    strands ``points`` / ``counts`` / ``widths`` (:func:`group_rest_statistics`) and, where it is
    None, the threshold at the densest node at rest; and that node relative to the rest density
    (None without hair-hair). ValueError for a grid of too many nodes."""
    hh = find(features, HairHair)
    if hh is None:
        return list(features), None
    typical, peak = group_rest_statistics(hh, points, counts, widths)
    rest, threshold = resolved(hh, typical, peak)
    return ([replace(f, rest_density=rest, threshold=threshold) if f is hh else f for f in features],
            peak * typical / rest)


def grid_weights(model, hh: HairHair, cell: float, shape=None) -> tuple[np.ndarray, float]:
    """What each particle splats (one per slot, 0 in unused slots): its hair volume fraction
    (:func:`volume_fractions`) over the groom's rest density (``hh.rest_density``, else
    :func:`rest_density` of this model's rest positions on the grid of node counts ``shape``), so
    the grid's density is 1 where the hair is as dense as it typically is at rest, whatever strands
    and vertices represent it; and the threshold (:func:`resolved`)."""
    lay = model.layout
    if lay.slot_of_point is None or model.rest_positions is None:
        raise ValueError("hair-hair interaction needs a model with host rest positions")
    points = model.rest_positions[lay.slot_of_point]
    fractions = volume_fractions(points, model.counts, model.widths, cell, hh.hair_width)
    rest, threshold = hh.rest_density, hh.threshold
    if rest is None or threshold is None:
        rest, threshold = resolved(hh, *rest_statistics(points, fractions, cell, shape))
    out = np.zeros(lay.num_slots)
    out[lay.slot_of_point] = fractions / rest
    return out, float(threshold)


def grid_dimensions(hh: HairHair, points, counts) -> tuple[tuple[int, int, int], float]:
    """(node counts (3,), cell size m) of the grid of ``hh`` for strands ``points``/``counts``."""
    cell = float(hh.cell_size)
    extent = hair_hair_extent(hh, points, counts)
    shape = tuple(int(np.ceil(e / cell)) + 3 for e in extent)
    if int(np.prod(shape)) > hh.max_cells:
        raise ValueError(f"hair-hair grid of {shape} nodes exceeds max_cells={hh.max_cells}; "
                         f"increase the cell ({cell:g} units: dftl:hairHairCellSize, or the API's cell_size) or "
                         "give a smaller extent")
    return shape, cell


class Grid:
    """The step's grid: ``arrays`` ``lower`` (3,) m, ``density`` and ``momentum`` per node.

    :meth:`rebuild` (the single-device step) finds the lower corner and splats every
    ``splat_interval``-th substep of a frame; :meth:`bounds` and :meth:`splat` are its two
    phases (a groom split across devices combines its parts' grids between them, every substep).
    The substeps of a frame are counted from their root fractions, which grow across a frame and
    start again at the next (a frame captured in a CUDA graph replays the rebuilds it captured).
    """

    def __init__(self, model, shape, cell: float):
        self.model = model
        self.shape = tuple(shape)
        self.cell = float(cell)
        hh = find(model.feature_data.features, HairHair) if model.feature_data is not None else None
        self.interval = int(hh.splat_interval) if hh is not None else 1
        self.by_strands = hh is not None and hh.splat == "strands"
        #: splat (interval - 1) dt / 2 ahead (False: at the positions themselves; for measurements)
        self.centred = True
        self._last_alpha = None
        self._substep = 0
        # what each particle splats (its hair volume fraction over the rest density's) and the
        # relative density below which it does not push
        weights, self.threshold = grid_weights(model, hh if hh is not None else HairHair(self.cell), self.cell,
                                               self.shape)
        self.arrays = {
            "weights": wp.array(weights, dtype=model.scalar, device=model.device),
            "lower": wp.zeros(3, dtype=model.scalar, device=model.device),
            "density": wp.zeros(self.shape, dtype=model.scalar, device=model.device),
            "momentum": wp.zeros(self.shape, dtype=model.vec3, device=model.device),
            # rebuilt every few substeps: the density splatted with the momentum (the grid velocity's
            # denominator), while "density" is splatted again every substep for the repulsion;
            # empty when every substep rebuilds (the momentum's density is "density" itself)
            "mass": wp.zeros(self.shape if self.interval > 1 else (0, 0, 0), dtype=model.scalar,
                             device=model.device),
        }

    def _splat_kernel(self, ahead: bool, density_only: bool = False):
        s = self.model.scalar
        if self.by_strands:
            return grid_splat_strands_kernel(s, ahead, density_only=density_only)
        return grid_splat_kernel(s, ahead, density_only=density_only)

    def kernels(self) -> list:
        s = self.model.scalar
        ks = [grid_reset_kernel(s), grid_bounds_strands_kernel(s), self._splat_kernel(False),
              self._splat_kernel(self.interval > 1)]
        if self.interval > 1:
            ks.append(self._splat_kernel(False, density_only=True))
        return ks

    def lead(self, dt: float) -> float:
        """How far ahead (s) a rebuild splats the particles along their velocities: ``(interval - 1)
        dt / 2``, centred on the substeps that use it (0 when not :attr:`centred`)."""
        return 0.5 * (self.interval - 1) * float(dt) if self.centred else 0.0

    def due(self, root_alpha: float) -> bool:
        """Whether the substep ending at root fraction ``root_alpha`` rebuilds the grid: the first
        of a frame (``root_alpha`` not above the previous substep's) and every ``interval``-th after."""
        alpha = float(root_alpha)
        if self._last_alpha is None or alpha <= self._last_alpha:
            self._substep = 0
        else:
            self._substep += 1
        self._last_alpha = alpha
        return self._substep % self.interval == 0

    def rebuild(self, positions, velocities, dt: float, root_alpha: float) -> bool:
        """Bounds and splat when :meth:`due` (the particles ``(interval - 1) dt / 2`` s ahead);
        returns whether it did. In the substeps between (``splat_interval`` > 1) the density alone
        is splatted again at the particles' positions: a repulsion from a density substeps old
        lags the motion it opposes and feeds energy into it (a dense groom moved twice as fast at
        interval 5, docs/features.md); the friction's grid velocity may lag, it only damps."""
        if not self.due(root_alpha):
            if self.interval > 1:
                self.splat_density(positions)
            return False
        self.bounds(positions)
        self.splat(positions, velocities, self.lead(dt))
        if self.interval > 1:
            self.splat_density(positions)
        return True

    def bounds(self, positions) -> None:
        """The lower corner from this model's particles (atomic min of each strand's minimum)."""
        m, g = self.model, self.arrays
        wp.launch(grid_reset_kernel(m.scalar), dim=1, device=m.device, outputs=[g["lower"]])
        wp.launch(grid_bounds_strands_kernel(m.scalar), dim=m.num_strands, device=m.device,
                  inputs=[m.strand_base, m.strand_stride, m.strand_count, positions], outputs=[g["lower"]])

    def splat(self, positions, velocities, lead: float = 0.0) -> None:
        """Density and momentum of this model's particles onto the grid (from ``lower``), each
        particle ``lead`` seconds ahead along its velocity (the density into ``mass`` when the grid
        keeps one: :meth:`splat_density` writes ``density``)."""
        g = self.arrays
        mass = g["mass"] if g["mass"].shape[0] else g["density"]
        mass.zero_()
        g["momentum"].zero_()
        self._launch(self._splat_kernel(lead != 0.0), positions, velocities, lead, mass)

    def splat_density(self, positions) -> None:
        """The density alone of this model's particles at ``positions`` onto ``density`` (from the
        last rebuild's ``lower``)."""
        g = self.arrays
        g["density"].zero_()
        self._launch(self._splat_kernel(False, density_only=True), positions, positions, 0.0, g["density"])

    def _launch(self, kernel, positions, velocities, lead: float, density) -> None:
        m, g = self.model, self.arrays
        tail = [g["weights"], g["lower"], 1.0 / self.cell, float(lead), *self.shape]
        if self.by_strands:
            wp.launch(kernel, dim=m.num_strands, device=m.device, block_dim=SPLAT_BLOCK_DIM,
                      inputs=[m.strand_base, m.strand_stride, m.strand_count, positions, velocities, *tail],
                      outputs=[density, g["momentum"]])
        else:
            wp.launch(kernel, dim=m.num_slots, device=m.device, inputs=[positions, velocities, *tail],
                      outputs=[density, g["momentum"]])

    def fill_struct(self, st, hh: HairHair) -> None:
        g = self.arrays
        st.grid_weights = g["weights"]
        st.grid_lower = g["lower"]
        st.grid_h = self.cell
        st.grid_inv_h = 1.0 / self.cell
        st.grid_nx, st.grid_ny, st.grid_nz = self.shape
        st.grid_density = g["density"]
        st.grid_momentum = g["momentum"]
        st.grid_mass = g["mass"]
        st.grid_friction = float(hh.friction)
        st.grid_repulsion = float(hh.repulsion)
        st.grid_threshold = self.threshold


def from_attributes(scene: dict, where: str, mean_segment: float, meters_per_unit: float = 1.0) -> list:
    """HairHair from authored ``dftl:hairHair*`` values; the default cell is 4 mean segments, the
    repulsion :data:`DEFAULT_REPULSION` m/s^2 and the width of hair without widths human hair's,
    both in stage units (``meters_per_unit``)."""
    if not authored(scene, "dftl:hairHair", where, bool, False):
        return []
    cell = authored(scene, "dftl:hairHairCellSize", where, float, 4.0 * mean_segment)
    if not cell > 0:
        raise ValueError(f"{where}: dftl:hairHairCellSize = {cell}: must be > 0")
    interval = authored(scene, "dftl:hairHairSplatInterval", where, int, 1)
    if interval < 1:
        raise ValueError(f"{where}: dftl:hairHairSplatInterval = {interval}: must be >= 1")
    return [HairHair(cell_size=cell, friction=authored(scene, "dftl:hairHairFriction", where, float, 2.0),
                     repulsion=authored(scene, "dftl:hairHairRepulsion", where, float,
                                        DEFAULT_REPULSION / meters_per_unit),  # m/s^2 in stage units
                     hair_width=DEFAULT_HAIR_WIDTH / meters_per_unit, splat_interval=interval,
                     threshold=authored(scene, "dftl:hairHairThreshold", where, float, None))]
