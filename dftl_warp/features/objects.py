"""Optional simulation features, described by plain Python objects built from numpy.

A scene turns a feature on by giving its object to the model
(``Model.from_strands(points, counts, widths=..., features=[...])``); the solver then compiles a
step specialized to exactly those features (``kernels/featured.py``), and a scene without any
runs the bare DFTL kernel. Units are SI (m, s, m/s, 1/s), or stage units consistently.

- :class:`Colliders` of :class:`Sphere`, :class:`Capsule`, :class:`Box` and :class:`TriangleMesh`
  shapes, each with a pose (position, rotation quaternion ``(x, y, z, w)``) that the Control can
  animate per frame, mesh points that it can deform per frame, and a Coulomb friction coefficient;
- :class:`RootBinding`: roots as barycentric points on a deforming triangle mesh;
- :class:`Drag` (air drag rate, 1/s) and :class:`Wind` (air velocity, constant or keyframed,
  optional curl noise); wind acts through drag;
- :class:`HairHair`: grid-based hair-hair friction and repulsion (Petrovic et al. 2005);
- :class:`ShapeRetention`: a rest-shape term in each strand's local frame (curls survive gravity).

:func:`feature_flags` gives the kernel flags of a feature list.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

_AXES = {"X": (1.0, 0.0, 0.0), "Y": (0.0, 1.0, 0.0), "Z": (0.0, 0.0, 1.0)}


def _vec(value, n, what):
    a = np.asarray(value, dtype=np.float64).reshape(-1)
    if a.shape != (n,) or not np.isfinite(a).all():
        raise ValueError(f"{what} must be {n} finite numbers, got {value!r}")
    return a


def _unit_quat(rotation, what="rotation"):
    q = _vec(rotation, 4, f"{what} (quaternion x, y, z, w)")
    norm = np.linalg.norm(q)
    if norm < 1e-12:
        raise ValueError(f"{what} quaternion is zero")
    return q / norm


def _nonnegative(value, what):
    value = float(value)
    if not np.isfinite(value) or value < 0.0:
        raise ValueError(f"{what} must be a finite number >= 0, got {value}")
    return value


# -- colliders -------------------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class _Shape:
    #: world position of the collider's local origin at rest, m
    position: np.ndarray = field(default_factory=lambda: np.zeros(3))
    #: world rotation at rest, unit quaternion (x, y, z, w)
    rotation: np.ndarray = field(default_factory=lambda: np.array([0.0, 0.0, 0.0, 1.0]))
    #: Coulomb friction coefficient (dimensionless, >= 0)
    friction: float = 0.3
    #: a name for messages (e.g. the USD prim path)
    name: str = ""

    def __post_init__(self):
        object.__setattr__(self, "position", _vec(self.position, 3, f"{self._label()} position"))
        object.__setattr__(self, "rotation", _unit_quat(self.rotation, f"{self._label()} rotation"))
        object.__setattr__(self, "friction", _nonnegative(self.friction, f"{self._label()} friction"))

    def _label(self):
        return f"{type(self).__name__.lower()} {self.name!r}" if self.name else type(self).__name__.lower()


@dataclass(frozen=True, eq=False)
class Sphere(_Shape):
    """A sphere of ``radius`` (m) centred on its local origin."""

    radius: float = 1.0
    kind = "spheres"

    def __post_init__(self):
        super().__post_init__()
        if not float(self.radius) > 0:
            raise ValueError(f"{self._label()} radius must be > 0, got {self.radius}")

    def size_axis(self):
        return (float(self.radius), 0.0, 0.0), (0.0, 0.0, 1.0)


@dataclass(frozen=True, eq=False)
class Capsule(_Shape):
    """A capsule: points within ``radius`` (m) of the segment of half length ``half_height`` (m)
    along the local ``axis`` ("X", "Y", "Z" as in UsdGeomCapsule, or a vector)."""

    radius: float = 1.0
    half_height: float = 1.0
    axis: object = "Z"
    kind = "capsules"

    def __post_init__(self):
        super().__post_init__()
        if not float(self.radius) > 0 or not float(self.half_height) >= 0:
            raise ValueError(f"{self._label()} needs radius > 0 and half_height >= 0")

    def size_axis(self):
        axis = np.asarray(_AXES[self.axis] if isinstance(self.axis, str) else self.axis, dtype=np.float64)
        axis = _vec(axis, 3, f"{self._label()} axis")
        return (float(self.radius), float(self.half_height), 0.0), tuple(axis / np.linalg.norm(axis))


@dataclass(frozen=True, eq=False)
class Box(_Shape):
    """A box of ``half_extents`` (3,) (m) centred on its local origin."""

    half_extents: np.ndarray = field(default_factory=lambda: np.ones(3))
    kind = "boxes"

    def __post_init__(self):
        super().__post_init__()
        h = _vec(self.half_extents, 3, f"{self._label()} half_extents")
        if np.any(h <= 0):
            raise ValueError(f"{self._label()} half_extents must be > 0")
        object.__setattr__(self, "half_extents", h)

    def size_axis(self):
        return tuple(self.half_extents), (0.0, 0.0, 1.0)


@dataclass(frozen=True, eq=False)
class TriangleMesh(_Shape):
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
        object.__setattr__(self, "depth_band", _nonnegative(band, f"{self._label()} depth_band"))

    def size_axis(self):
        return (0.0, 0.0, 0.0), (0.0, 0.0, 1.0)


SHAPE_KINDS = ("spheres", "capsules", "boxes", "meshes")


@dataclass(frozen=True, eq=False)
class Colliders:
    """Collision with ``shapes``: a particle of radius half its hair width stays outside.

    ``iterations``: rounds of collide-then-restore-rest-length per particle in the sweep (>= 1).
    Shapes are animated through the Control (``control.features.set_collider_poses``,
    ``set_mesh_points``), indexed in the order given here.
    """

    shapes: tuple = ()
    iterations: int = 2

    def __post_init__(self):
        shapes = tuple(self.shapes)
        for i, s in enumerate(shapes):
            if not isinstance(s, (Sphere, Capsule, Box, TriangleMesh)):
                raise ValueError(f"collider {i} is a {type(s).__name__}, not a Sphere, Capsule, Box or TriangleMesh")
        object.__setattr__(self, "shapes", shapes)
        if int(self.iterations) < 1:
            raise ValueError(f"collider iterations must be >= 1, got {self.iterations}")

    @property
    def flags(self):
        return frozenset(s.kind for s in self.shapes)


# -- roots on a deforming mesh -----------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class RootBinding:
    """Roots bound to a deforming triangle mesh: each root is a barycentric point on a triangle.

    ``points`` (P, 3) world rest positions (m), ``indices`` (T, 3). ``triangles`` (S,) and
    ``weights`` (S, 3) per input strand, or ``None`` to bind each root to the closest point of
    the rest mesh. Animate with ``control.features.set_binding_points(start, end)``.
    Costs nothing per step: the root targets are computed once per frame.
    """

    points: np.ndarray
    indices: np.ndarray
    triangles: np.ndarray | None = None
    weights: np.ndarray | None = None

    def __post_init__(self):
        pts = np.asarray(self.points, dtype=np.float64).reshape(-1, 3)
        idx = np.asarray(self.indices, dtype=np.int64).reshape(-1, 3)
        if idx.size == 0 or idx.min() < 0 or idx.max() >= len(pts):
            raise ValueError("root binding mesh: indices must reference its points")
        object.__setattr__(self, "points", pts)
        object.__setattr__(self, "indices", idx.astype(np.int32))
        if (self.triangles is None) != (self.weights is None):
            raise ValueError("root binding: give both triangles and weights, or neither")

    flags = frozenset()


# -- air -----------------------------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class Drag:
    """Air drag: velocities relax toward the air's at ``rate`` (1/s), ``v = w + (v - w) exp(-rate dt)``.

    ``rate`` is a number or one per input strand (per curve)."""

    rate: object = 1.0

    def __post_init__(self):
        r = np.asarray(self.rate, dtype=np.float64)
        if not np.isfinite(r).all() or np.any(r < 0):
            raise ValueError("drag rate must be finite and >= 0 (1/s)")
        object.__setattr__(self, "rate", r)

    flags = frozenset({"drag"})


@dataclass(frozen=True, eq=False)
class Wind:
    """Air velocity (m/s) for :class:`Drag`: ``velocity`` (3,) constant, or keyframes (K, 4) of
    ``(time s, vx, vy, vz)`` interpolated linearly (held before the first and after the last).

    ``noise_amplitude`` (m/s) adds divergence-free curl noise of feature size ``noise_scale`` (m)
    changing at ``noise_frequency`` (1/s), field chosen by ``seed``."""

    velocity: np.ndarray = field(default_factory=lambda: np.zeros(3))
    noise_amplitude: float = 0.0
    noise_scale: float = 0.1
    noise_frequency: float = 1.0
    seed: int = 0

    def __post_init__(self):
        v = np.asarray(self.velocity, dtype=np.float64)
        if v.shape == (3,):
            v = np.concatenate([[0.0], v])[None]
        if v.ndim != 2 or v.shape[1] != 4 or len(v) == 0 or not np.isfinite(v).all():
            raise ValueError("wind velocity must be (3,) or keyframes (K, 4) of (time, vx, vy, vz)")
        if np.any(np.diff(v[:, 0]) < 0):
            raise ValueError("wind keyframe times must increase")
        object.__setattr__(self, "velocity", v)
        _nonnegative(self.noise_amplitude, "wind noise_amplitude")
        if not float(self.noise_scale) > 0:
            raise ValueError("wind noise_scale must be > 0 (m)")

    def at(self, time: float) -> np.ndarray:
        """Wind velocity (3,) at ``time`` (s)."""
        k = self.velocity
        return np.array([np.interp(time, k[:, 0], k[:, c]) for c in (1, 2, 3)])

    @property
    def flags(self):
        return frozenset({"wind", "wind_noise"} if self.noise_amplitude > 0 else {"wind"})


# -- hair-hair, shape ---------------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class HairHair:
    """Hair-hair interaction on a grid of ``cell_size`` (m) that follows the hair.

    ``friction`` (1/s): rate at which velocities relax toward the grid (local mean) velocity;
    ``repulsion`` (m/s^2): acceleration per unit density difference (particles per grid node)
    across one cell, pushing particles toward lower density. ``extent`` (3,), m: the grid's size,
    by default the rest bounds of the hair plus twice the longest strand on each axis, capped
    at ``max_cells`` nodes (particles outside the grid feel nothing).
    """

    cell_size: float
    friction: float = 2.0
    repulsion: float = 5.0
    extent: np.ndarray | None = None
    max_cells: int = 1 << 24

    def __post_init__(self):
        if not float(self.cell_size) > 0:
            raise ValueError(f"hair-hair cell_size must be > 0 (m), got {self.cell_size}")
        _nonnegative(self.friction, "hair-hair friction")
        _nonnegative(self.repulsion, "hair-hair repulsion")

    flags = frozenset({"hair_hair"})


@dataclass(frozen=True, eq=False)
class ShapeRetention:
    """Keep each strand's rest shape (curls, styling) in its own local frame.

    ``stiffness`` in [0, 1], a number or one per input strand (0 turns it off for that curve):
    the share of the way each prediction moves toward its rest-shape target per substep."""

    stiffness: object = 0.5

    def __post_init__(self):
        s = np.asarray(self.stiffness, dtype=np.float64)
        if not np.isfinite(s).all() or np.any(s < 0) or np.any(s > 1):
            raise ValueError("shape retention stiffness must be in [0, 1]")
        object.__setattr__(self, "stiffness", s)

    flags = frozenset({"shape"})


FEATURE_TYPES = (Colliders, RootBinding, Drag, Wind, HairHair, ShapeRetention)


def check_features(features) -> tuple:
    """Validate a feature list: known types, at most one of each, wind only with drag."""
    features = tuple(features or ())
    seen = set()
    for f in features:
        if not isinstance(f, FEATURE_TYPES):
            raise ValueError(f"unknown feature {f!r}; use one of {', '.join(t.__name__ for t in FEATURE_TYPES)}")
        if type(f) in seen:
            raise ValueError(f"feature {type(f).__name__} given twice")
        seen.add(type(f))
    if Wind in seen and Drag not in seen:
        raise ValueError("Wind acts through air drag: add a Drag feature")
    return features


def feature_flags(features) -> frozenset:
    """Kernel flags of ``features`` (the empty set for a gravity-only scene)."""
    flags = frozenset()
    for f in check_features(features):
        flags |= f.flags
    return flags


def find(features, kind):
    """The feature of type ``kind`` in ``features``, or None."""
    for f in features or ():
        if isinstance(f, kind):
            return f
    return None
