"""What was read from a USD stage: plain data, no USD objects (a Scene pickles; no stage stays open).

:func:`dftl_warp.usd.read.read_scene` builds a :class:`Scene`; the simulation
(:mod:`dftl_warp.simulation.simulate`) and the writer (:mod:`dftl_warp.output.usd`) consume it. Every length is
in *stage units* (``metersPerUnit`` metres each); times are in *time codes*
(``timeCodesPerSecond`` per second).

Matrices follow USD's row-vector convention: a local point ``p`` (row) maps to the world as
``[p, 1] @ M``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import numpy as np

#: 4x4 local-to-world matrix (row-vector convention) at a time code
TransformSampler = Callable[[float], np.ndarray]


class Samples:
    """A value read at time codes ``times`` (K,), ``values`` (K, ...): calling it with a time code
    returns the sample there, interpolates linearly between samples (held: the earlier sample)
    and holds the first/last sample outside them, as USD does. Plain data: it pickles."""

    def __init__(self, times, values, held: bool = False):
        self.times = np.asarray(times, dtype=np.float64).reshape(-1)
        self.values = np.asarray(values, dtype=np.float64)
        if self.times.shape[0] == 0 or self.values.shape[0] != self.times.shape[0]:
            raise ValueError("Samples need one value per time, at least one")
        if np.any(np.diff(self.times) <= 0):
            raise ValueError("Samples need increasing times")
        self.values.setflags(write=False)
        self.held = bool(held)

    def __call__(self, time) -> np.ndarray:
        t = self.times[0] if time is None else float(time)
        k = int(np.searchsorted(self.times, t, side="right")) - 1
        if k < 0:
            return self.values[0]
        if k >= self.times.shape[0] - 1 or self.times[k] == t or self.held:
            return self.values[k]
        u = (t - self.times[k]) / (self.times[k + 1] - self.times[k])
        return (1.0 - u) * self.values[k] + u * self.values[k + 1]

    def __repr__(self) -> str:
        return f"Samples({self.times.shape[0]} times {self.times[0]:g}..{self.times[-1]:g}, {self.values.shape[1:]})"


class Constant:
    """The same value at every time code (a static transform or mesh). Plain data: it pickles."""

    def __init__(self, value):
        self.value = np.array(value, dtype=np.float64)
        self.value.setflags(write=False)

    def __call__(self, time=None) -> np.ndarray:
        return self.value

    def __repr__(self) -> str:
        return f"Constant({self.value.shape})"


def constant_transform(matrix=None) -> TransformSampler:
    """A sampler that returns ``matrix`` (identity by default) at every time code."""
    return Constant(np.eye(4) if matrix is None else np.asarray(matrix, dtype=np.float64).reshape(4, 4))


def transform_points(matrix: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Points (N, 3) through a 4x4 row-vector matrix (affine)."""
    return points @ matrix[:3, :3] + matrix[3, :3]


@dataclass
class StageInfo:
    """Stage metadata, effective values (USD fallbacks applied) plus what was authored."""

    #: "Y" or "Z"
    up_axis: str = "Y"
    #: metres per stage unit (0.01 when unauthored, as USD specifies)
    meters_per_unit: float = 0.01
    #: kilograms per stage mass unit (UsdPhysics ``kilogramsPerUnit``; 1 when unauthored)
    kilograms_per_unit: float = 1.0
    #: time codes per second (the frame rate of the simulation)
    time_codes_per_second: float = 24.0
    #: ``framesPerSecond`` if authored
    frames_per_second: float | None = None
    #: authored ``startTimeCode`` / ``endTimeCode`` (None when the stage has no time code range)
    start_time_code: float | None = None
    end_time_code: float | None = None
    #: authored ``defaultPrim`` ("" when none)
    default_prim: str = ""
    #: names of the metadata fields the root layer authors (``upAxis``, ``metersPerUnit`` ...)
    authored: tuple[str, ...] = ()


@dataclass
class CurveSettings:
    """Per-prim ``dftl:`` settings (None: not authored; the command line or defaults decide)."""

    simulate: bool = True
    solver: str | None = None
    damping: float | None = None
    correction: str | None = None
    substeps: int | None = None
    inverse_statics: bool | None = None
    #: ``dftl:bending``: False keeps a prim with widths on the DFTL chain when no solver is set
    bending: bool | None = None


@dataclass
class CurveMaterial:
    """A bound curve-deformable physics material (``PhysicsCurvesDeformableMaterialAPI``), in stage
    units (UsdPhysics: mass in ``kilogramsPerUnit``, length in ``metersPerUnit``); None: not
    authored. ``bend_stiffness`` is E*I and ``twist_stiffness`` G*J (``physics:curvesBendStiffness``,
    ``physics:curvesTwistStiffness``)."""

    path: str
    youngs_modulus: float | None = None
    poissons_ratio: float | None = None
    density: float | None = None
    bend_stiffness: float | None = None
    twist_stiffness: float | None = None


@dataclass
class MeshSource:
    """A UsdGeom.Mesh the roots of a curves prim are bound to (``dftl:rootMesh``)."""

    path: str
    #: (T, 3) int64 triangles (fan-triangulated faces)
    triangles: np.ndarray
    #: local points (V, 3) at a time code (:class:`Samples` or :class:`Constant`)
    points: Callable[[float], np.ndarray]
    transform: TransformSampler = field(default_factory=constant_transform)
    #: whether points or transform may change over time
    animated: bool = False

    def world_points(self, time) -> np.ndarray:
        return transform_points(self.transform(time), self.points(time))


@dataclass
class CurvesPrim:
    """One UsdGeom.BasisCurves prim: its strands in local space (stage units)."""

    path: str
    #: (N, 3) float64 control points in the prim's local space, read at the read time code
    points: np.ndarray
    #: (S,) int64 vertex count of each curve; vertex 0 of each curve is its root
    counts: np.ndarray
    #: "linear" or "cubic"
    type: str = "linear"
    #: "bezier", "bspline", "catmullRom" (meaningful for cubic curves)
    basis: str = "bezier"
    #: "nonperiodic" or "pinned" (periodic curves are refused by the reader)
    wrap: str = "nonperiodic"
    #: widths (stage units) as authored, and their interpolation ("" when none)
    widths: np.ndarray | None = None
    widths_interpolation: str = ""
    #: displayColor as authored (K, 3) and its interpolation, if any
    display_color: np.ndarray | None = None
    display_color_interpolation: str = ""
    #: local-to-world matrix at a time code (:class:`Samples` read for the run's frames, or
    #: :class:`Constant`)
    transform: TransformSampler = field(default_factory=constant_transform)
    #: whether the local-to-world transform may change over time
    animated: bool = False
    settings: CurveSettings = field(default_factory=CurveSettings)
    #: authored per-curve feature values (``dftl:drag``; see docs/features.md)
    features: dict = field(default_factory=dict)
    #: the mesh the roots are bound to (``dftl:rootMesh``), if any
    root_mesh: MeshSource | None = None
    #: the bound curve-deformable physics material (elastic solver), if any
    material: CurveMaterial | None = None
    #: ``physics:restShapePoints`` (N, 3) local, stage units, if authored (elastic solver)
    rest_points: np.ndarray | None = None
    #: ``primvars:dftl:bendStiffnessScale`` per vertex (N,), if authored (elastic solver)
    bend_scale: np.ndarray | None = None
    #: the authored normal attributes (``normals``, ``primvars:normals``): they describe the rest
    #: shape, so the output blocks them rather than leave them behind the moving points
    normals: tuple = ()
    #: ``rel dftl:guides``: paths of the guide BasisCurves prims this render prim follows (docs/guides.md);
    #: empty: the prim is simulated
    guides: tuple = ()

    @property
    def num_strands(self) -> int:
        return int(self.counts.shape[0])

    @property
    def num_points(self) -> int:
        return int(self.points.shape[0])

    @property
    def root_indices(self) -> np.ndarray:
        """Index of each curve's root (vertex 0) in :attr:`points`."""
        starts = np.zeros(self.counts.shape[0], dtype=np.int64)
        np.cumsum(self.counts[:-1], out=starts[1:])
        return starts


@dataclass
class ColliderPrim:
    """A prim with UsdPhysics.CollisionAPI, in its local space (stage units).

    ``kind`` is "sphere" (``radius``), "capsule" (``radius``, ``height`` of the cylinder part,
    ``axis``), "box" (``half_extents``) or "mesh" (``mesh_points``, ``triangles``); for a prim of
    another accepted type (:func:`dftl_warp.usd.colliders.accept_collider_type`) it is the prim's
    type name (``"Cylinder"``) and ``attributes`` holds its attribute values.
    """

    path: str
    kind: str
    radius: float = 0.0
    height: float = 0.0
    axis: str = "Z"
    #: (3,) half sizes of a box
    half_extents: np.ndarray | None = None
    #: (V, 3) float64 mesh vertices and (T, 3) int64 triangle indices (fan-triangulated faces)
    mesh_points: np.ndarray | None = None
    triangles: np.ndarray | None = None
    #: Coulomb friction coefficient: ``dftl:friction`` if authored, else the bound physics
    #: material's dynamicFriction, else None
    friction: float | None = None
    transform: TransformSampler = field(default_factory=constant_transform)
    animated: bool = False
    #: local mesh points at a time code, for a mesh whose points are time-sampled (else None)
    points_sampler: Callable[[float], np.ndarray] | None = None
    #: attribute name -> value (plain data) of a generically read prim (empty for the built-in kinds)
    attributes: dict = field(default_factory=dict)


@dataclass
class Scene:
    """Everything the simulator needs from one stage."""

    #: the file that was read (as given)
    source: str
    stage: StageInfo
    #: (3,) gravity, stage units / s^2
    gravity: np.ndarray
    curves: list[CurvesPrim] = field(default_factory=list)
    colliders: list[ColliderPrim] = field(default_factory=list)
    #: the time code the points were read at (None: the default time)
    read_time: float | None = None
    #: one-line diagnostics USD reported while opening the stage (missing sublayers ...)
    warnings: list[str] = field(default_factory=list)
    #: authored scene-wide feature values (``dftl:wind``, ``dftl:hairHair`` ...; docs/features.md),
    #: from the UsdPhysics.Scene prim, else the default prim; ``dftl:wind`` as keyframes (K, 4)
    #: of (seconds, vx, vy, vz) when time-sampled
    features: dict = field(default_factory=dict)

    @property
    def num_strands(self) -> int:
        return sum(c.num_strands for c in self.curves)

    @property
    def num_points(self) -> int:
        return sum(c.num_points for c in self.curves)

    @property
    def gravity_si(self) -> np.ndarray:
        """Gravity in m/s^2."""
        return self.gravity * self.stage.meters_per_unit
