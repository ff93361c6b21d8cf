"""The Model: an immutable description of the strands to simulate.

A Model holds what does not change during a simulation: strand topology (vertex counts), rest
lengths, the particle layout, the roots' rest positions and the world origin the device arrays are
relative to. Everything lives on one Warp device in one precision. Build it with
:meth:`Model.from_strands`; make :class:`~dftl_warp.core.state.State` and
:class:`~dftl_warp.core.state.Control` objects from it.

Units: positions in metres (or stage units, consistently), lengths likewise.
"""

from __future__ import annotations

from dataclasses import dataclass
from numbers import Integral

import numpy as np
import warp as wp

from ..checks import check_lengths
from .bounds import box
from .devices import device_argument
from .layout import (LAYOUTS, MAX_SLOTS, Layout, default_interleave, default_layout, incoming_lengths, make_layout,
                     read_only, strand_offsets)
from .precision import numpy_type, scalar_type, vec3_type
from .state import feature_hook

#: diameter (m) of human hair (about 80 um; Robbins 2002), taken where a model gives no widths (the
#: elastic solver's radius, the hair-hair grid's hair volume)
DEFAULT_HAIR_WIDTH = 80e-6


def _world_origin(points: np.ndarray) -> np.ndarray:
    """Origin subtracted on upload so that float32 keeps its precision far from (0, 0, 0).

    Zero for scenes near the origin (so coordinates round-trip exactly); the centre of the
    bounds, rounded to float32, for scenes far away relative to their size.
    """
    if points.shape[0] == 0:
        return np.zeros(3)
    lo, hi = box(points)
    centre = 0.5 * (lo + hi)
    extent = float(np.max(hi - lo))
    if np.linalg.norm(centre) <= 16.0 * max(extent, 1.0e-30) or np.linalg.norm(centre) < 1.0:
        return np.zeros(3)
    return centre.astype(np.float32).astype(np.float64)


@dataclass(frozen=True, eq=False)
class Model:
    """Immutable strand model on a device. Construct with :meth:`from_strands`.

    Its host numpy arrays (``counts``, ``origin``, ``rest_positions``, ``widths`` and the
    layout's) are read-only views. ``dataclasses.replace`` keeps the device arrays, so it cannot
    change the precision or the device (ValueError): build another model with :meth:`from_strands`.
    """

    device: wp.Device
    precision: str
    layout: Layout
    #: vertex count of each strand, input order
    counts: np.ndarray
    #: world position (float64, metres) that device coordinates are relative to
    origin: np.ndarray
    strand_base: wp.array
    strand_stride: wp.array
    strand_count: wp.array
    #: rest length of the segment ending at each particle (0 at roots), layout order, metres
    rest_lengths: wp.array
    #: initial positions (host numpy), layout order, relative to ``origin``
    rest_positions: np.ndarray
    #: initial root positions per device strand, relative to ``origin``
    root_rest: wp.array
    #: the optional features (:mod:`dftl_warp.features`) given at build time
    features: tuple = ()
    #: their device data (:class:`~dftl_warp.features.step.ModelFeatures`), None without features
    feature_data: object = None
    #: hair diameters as given to :meth:`from_strands` (one value, or one per point in input
    #: order; stage units), None when not given: the colliders' contact distance and the elastic
    #: solver's default radius
    widths: np.ndarray | None = None

    def __post_init__(self):
        for name in ("counts", "origin", "rest_positions", "widths"):   # edits in place were taken silently
            object.__setattr__(self, name, read_only(getattr(self, name)))
        # dataclasses.replace(model, precision="float64") kept the float32 arrays: Warp's launch failed
        # with "expects an array with dtype=vec_t but passed array has dtype=vec_t"
        arrays = self.rest_lengths
        if arrays.dtype is not scalar_type(self.precision) or str(arrays.device) != str(self.device):
            raise ValueError(f"Model: precision {self.precision!r} on {self.device} does not match its arrays "
                             f"({wp.types.type_repr(arrays.dtype)} on {arrays.device}): a model's precision and "
                             f"device are fixed when it is built; build another with Model.from_strands(..., "
                             f"precision={self.precision!r}, device={str(self.device)!r})")

    @property
    def num_strands(self) -> int:
        return int(self.counts.shape[0])

    @property
    def num_points(self) -> int:
        """Particles (vertices) of the groom."""
        return self.layout.num_points

    @property
    def num_slots(self) -> int:
        """Length of every per-particle device array (more than ``num_points`` when the layout
        interleaves state vectors: :mod:`dftl_warp.core.layout`)."""
        return int(self.rest_lengths.shape[0])

    @property
    def scalar(self):
        return scalar_type(self.precision)

    @property
    def vec3(self):
        return vec3_type(self.precision)

    @property
    def feature_flags(self) -> frozenset:
        """Kernel flags of the model's features; empty for a gravity-only scene."""
        return self.feature_data.flags if self.feature_data is not None else frozenset()

    @classmethod
    def from_strands(
        cls,
        points,
        counts,
        *,
        device="cpu",
        precision: str = "float32",
        layout: str | None = None,
        widths=None,
        features=None,
        origin=None,
        interleave: int | None = None,
        corrections: bool = True,
    ) -> Model:
        """Model of strands given as concatenated ``points`` (N, 3) and vertex ``counts`` (S,).

        Vertex 0 of each strand is its root. Rest lengths are the input's segment lengths.
        ``layout`` defaults to the fastest for ``device`` (:func:`~dftl_warp.core.layout.default_layout`).
        ``features``: optional feature objects (:mod:`dftl_warp.features`); ``widths``: hair
        diameter (m), one value or one per point, used as the contact distance of colliders.
        ``origin`` (3,) overrides the world origin (models sharing one give identical results).
        ``interleave``: state vectors per 32-strand chunk of a particle-major layout (default
        :func:`~dftl_warp.core.layout.default_interleave`: on CUDA without features, 3, or 2 when
        ``corrections`` is False: the solver carries none, :func:`~dftl_warp.solvers.dftl.carries_corrections`).

        ValueError for ``points`` that are not (N, 3) (a flat array of x, y, z triples is taken),
        ``counts`` that are not whole numbers, ``widths`` of another length than one or one per
        point, non-finite or negative, whatever the features, and an ``origin`` that is not 3 finite
        numbers.
        """
        points, counts = check_strand_arrays(points, counts)
        widths = _checked_widths(widths, points.shape[0])
        if not isinstance(corrections, (bool, np.bool_)):   # "no" was taken as True
            raise ValueError(f"corrections must be True or False, got {corrections!r}")
        features = _feature_tuple(features)
        if interleave is not None and (isinstance(interleave, (bool, np.bool_))
                                       or not isinstance(interleave, Integral)):
            raise ValueError(f"interleave must be a whole number of state vectors, got {interleave!r}")
        device = device_argument(device)
        layout_name = layout or default_layout(str(device))
        if layout_name not in LAYOUTS:
            raise ValueError(f"unknown layout {layout_name!r}; choose one of {', '.join(LAYOUTS)}")
        default = interleave is None
        if default:
            interleave = default_interleave(layout_name, str(device), bool(features), corrections)
        first = points[strand_offsets(counts)] if counts.size else None   # the roots: warps of neighbours
        lay = make_layout(counts, layout_name, interleave, roots=first)
        if default and lay.storage_length > MAX_SLOTS:
            lay = make_layout(counts, layout_name, 1, roots=first)
        if precision == "float32":   # finite in float64, inf (or its square inf) in the float32 model
            check_lengths(points, "points", "", error=ValueError)
        origin = _world_origin(points) if origin is None else _checked_origin(origin, precision)
        local = points - origin

        starts = strand_offsets(counts)
        seg = incoming_lengths(points, counts)

        ftype = numpy_type(precision)
        rest = np.zeros(lay.num_slots, dtype=ftype)
        rest[lay.slot_of_point] = seg
        pos = np.zeros((lay.num_slots, 3), dtype=ftype)
        pos[lay.slot_of_point] = local
        roots = local[starts[lay.strand_order]].astype(ftype) if counts.size else np.zeros((0, 3), ftype)

        vec3 = vec3_type(precision)
        feature_data = None
        if features:
            feature_data = feature_hook("build")(
                dict(device=device, precision=precision, layout=lay, scalar=scalar_type(precision), vec3=vec3,
                     counts=counts, points=points, origin=origin),
                features, widths=widths)
        i32 = lambda a: wp.array(np.ascontiguousarray(a, dtype=np.int32), dtype=wp.int32, device=device)  # noqa: E731
        return cls(
            device=device,
            precision=precision,
            layout=lay,
            counts=counts,
            origin=origin,
            strand_base=i32(lay.strand_base),
            strand_stride=i32(lay.strand_stride),
            strand_count=i32(lay.strand_count),
            rest_lengths=wp.array(rest, dtype=scalar_type(precision), device=device),
            rest_positions=pos,
            root_rest=wp.array(roots, dtype=vec3, device=device),
            features=features,
            feature_data=feature_data,
            widths=None if widths is None else np.array(widths, dtype=np.float64),   # a copy: the caller's may change
        )

    # -- conversions between the caller's order/world space and the device layout ---------------

    def points_to_device(self, points, *, relative: bool = True) -> np.ndarray:
        """(N, 3) world points in input order -> layout-ordered numpy array in model precision.

        ``relative=False`` is for vectors (velocities), which the origin does not shift."""
        points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        out = np.zeros((self.num_slots, 3), dtype=numpy_type(self.precision))
        out[self.layout.slot_of_point] = points - self.origin if relative else points
        return out

    def points_from_device(self, array, *, relative: bool = True) -> np.ndarray:
        """Layout-ordered device array -> (N, 3) float64 numpy in input order (world space)."""
        host = array.numpy() if isinstance(array, wp.array) else np.asarray(array)
        out = host[self.layout.slot_of_point].astype(np.float64)
        return out + self.origin if relative else out

    def roots_to_device(self, roots, what: str = "root targets") -> np.ndarray:
        """(S, 3) world root targets in input strand order -> device strand order, model precision.
        ValueError naming ``what`` unless they are S finite rows of 3 (one per strand)."""
        try:
            roots = np.asarray(roots, dtype=np.float64)
        except (TypeError, ValueError):
            raise ValueError(f"{what} must be numbers: an (S, 3) array, one row per strand") from None
        if roots.shape != (self.num_strands, 3):
            raise ValueError(f"{what} must have shape ({self.num_strands}, 3), one row per strand, "
                             f"got {roots.shape}")
        bad = ~np.isfinite(roots).all(axis=1)
        if bad.any():
            raise ValueError(f"{what}: row {int(np.argmax(bad))} is not finite")
        if self.precision == "float32":
            check_lengths(roots, what, "", error=ValueError)
        return (roots[self.layout.strand_order] - self.origin).astype(numpy_type(self.precision))

    # -- factories ---------------------------------------------------------------------------------

    def state(self, *, with_corrections: bool = True):
        """A State at rest: input positions, zero velocities (and zero carried corrections)."""
        from .state import State

        return State.at_rest(self, with_corrections=with_corrections)

    def control(self):
        """A Control whose root targets hold the roots at their rest positions."""
        from .state import Control

        return Control.at_rest(self)


def check_strand_arrays(points, counts, least: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """(points (N, 3) float64, counts (S,) int64) of strands given as concatenated ``points`` and
    vertex ``counts``, or a ValueError naming the first bad index: counts that are not whole
    numbers or below ``least`` (a renderer draws nothing for 0; a model needs a root), that do not
    sum to the points, or a point that is not finite."""
    try:
        points = np.asarray(points, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError("points must be numbers: an (N, 3) array") from None
    # an (N, 2) or (N, 4) array was reshaped to (N', 3) without a word: x, y pairs or homogeneous
    # coordinates became other points; only (..., 3) or a flat run of x, y, z triples is taken
    if points.size % 3 or (points.ndim > 1 and points.shape[-1] != 3):
        raise ValueError(f"points must have shape (N, 3), got {points.shape}")
    points = points.reshape(-1, 3)
    counts = _checked_counts(counts)
    if np.any(counts < least):
        i = int(np.flatnonzero(counts < least)[0])
        need = "a vertex count cannot be negative" if least == 0 else f"every strand needs at least {least}"
        raise ValueError(f"strand {i} has {counts[i]} vertices; {need}")
    if int(counts.sum()) != points.shape[0]:
        raise ValueError(f"vertex counts sum to {int(counts.sum())} but there are {points.shape[0]} points")
    bad = ~np.isfinite(points).all(axis=1)
    if bad.any():
        raise ValueError(f"point {int(np.flatnonzero(bad)[0])} is not finite")
    return points, counts


def _checked_counts(counts) -> np.ndarray:
    """``counts`` as (S,) int64; ValueError naming the first strand whose count is not a whole number."""
    c = np.asarray(counts)
    if c.dtype == np.bool_ or not (np.issubdtype(c.dtype, np.integer) or np.issubdtype(c.dtype, np.floating)
                                   or c.size == 0):
        raise ValueError(f"counts must be whole numbers of vertices per strand, got {counts!r}")
    c = c.reshape(-1)
    if np.issubdtype(c.dtype, np.floating):
        bad = ~np.isfinite(c) | (c != np.round(c))
        if bad.any():
            i = int(np.flatnonzero(bad)[0])
            raise ValueError(f"counts[{i}] = {float(c[i])!r} is not a whole number of vertices")
    return c.astype(np.int64)


def _checked_origin(origin, precision: str = "float64") -> np.ndarray:
    """``origin`` as a (3,) float64 array; ValueError naming it unless it is 3 finite numbers (a NaN
    origin made every device position NaN), each small enough for a float32 ``precision``."""
    try:
        o = np.array(origin, dtype=np.float64)   # a copy: the caller's may change
    except (TypeError, ValueError):
        raise ValueError(f"origin must be 3 finite numbers (m), got {origin!r}") from None
    if o.size != 3 or not np.isfinite(o).all():
        raise ValueError(f"origin must be 3 finite numbers (m), got {origin!r}")
    if precision == "float32":   # the points, stored relative to it, collapsed
        check_lengths(o.reshape(1, 3), "origin", "", indexed=False, error=ValueError)
    return o.reshape(3)


def _checked_widths(widths, num_points: int):
    """``widths`` (one value or one per point) as a float64 array, or None; ValueError naming it
    for another length, a non-finite or a negative value."""
    if widths is None:
        return None
    try:
        w = np.asarray(widths, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"widths must be numbers (m), got {widths!r}") from None
    if w.size != 1 and w.reshape(-1).shape != (num_points,):
        raise ValueError(f"widths must be one value or one per point ({num_points}), got {w.size} values")
    flat = w.reshape(-1)
    bad = ~np.isfinite(flat) | (flat < 0)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise ValueError(f"widths[{i}] = {float(flat[i])!r} must be finite and >= 0 (m)")
    return w


def _feature_tuple(features) -> tuple:
    """``features`` (None, or a list of feature objects) as a tuple; one feature object given alone
    is a TypeError saying so ("'Drag' object is not iterable" named neither)."""
    if features is None:
        return ()
    try:
        return tuple(features)
    except TypeError:
        raise TypeError(f"features must be a list of feature objects (dftl_warp.features), got one "
                        f"{type(features).__name__}: features=[{type(features).__name__}(...)]") from None
