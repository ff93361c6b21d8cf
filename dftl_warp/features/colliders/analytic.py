"""Analytic collider shapes: :class:`Sphere`, :class:`Capsule`, :class:`Box`.

Their geometry travels in the common per-collider ``size`` and ``axis`` vectors (m); their
surfaces are the signed-distance functions of ``kernels/features/analytic.py``. USD:
UsdGeomSphere, UsdGeomCapsule, UsdGeomCube, their scale baked in (a sphere takes its largest
scale, a capsule the largest across its axis, a box its scale per axis).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ...kernels.features.analytic import BOX, CAPSULE, SPHERE
from ..base import vector
from .base import ColliderShape

_AXES = {"X": (1.0, 0.0, 0.0), "Y": (0.0, 1.0, 0.0), "Z": (0.0, 0.0, 1.0)}
_AXIS_INDEX = {"X": 0, "Y": 1, "Z": 2}


@dataclass(frozen=True, eq=False)
class Sphere(ColliderShape):
    """A sphere of ``radius`` (m) centred on its local origin."""

    radius: float = 1.0
    kind = "spheres"
    kernel = SPHERE
    usd_kind = "sphere"

    def __post_init__(self):
        super().__post_init__()
        if not float(self.radius) > 0:
            raise ValueError(f"{self._label()} radius must be > 0, got {self.radius}")

    def size_axis(self):
        return (float(self.radius), 0.0, 0.0), (0.0, 0.0, 1.0)

    @classmethod
    def from_prim(cls, prim, position, rotation, scale, common):
        return cls(radius=prim.radius * np.abs(scale).max(), **common)


@dataclass(frozen=True, eq=False)
class Capsule(ColliderShape):
    """A capsule: points within ``radius`` (m) of the segment of half length ``half_height`` (m)
    along the local ``axis`` ("X", "Y", "Z" as in UsdGeomCapsule, or a vector)."""

    radius: float = 1.0
    half_height: float = 1.0
    axis: object = "Z"
    kind = "capsules"
    kernel = CAPSULE
    usd_kind = "capsule"

    def __post_init__(self):
        super().__post_init__()
        if not float(self.radius) > 0 or not float(self.half_height) >= 0:
            raise ValueError(f"{self._label()} needs radius > 0 and half_height >= 0")

    def size_axis(self):
        axis = np.asarray(_AXES[self.axis] if isinstance(self.axis, str) else self.axis, dtype=np.float64)
        axis = vector(axis, 3, f"{self._label()} axis")
        return (float(self.radius), float(self.half_height), 0.0), tuple(axis / np.linalg.norm(axis))

    @classmethod
    def from_prim(cls, prim, position, rotation, scale, common):
        a = np.abs(scale)
        axis = _AXIS_INDEX.get(str(prim.axis).upper(), 2)
        across = np.delete(a, axis).max()
        return cls(radius=prim.radius * across, half_height=0.5 * prim.height * a[axis], axis="XYZ"[axis], **common)


@dataclass(frozen=True, eq=False)
class Box(ColliderShape):
    """A box of ``half_extents`` (3,) (m) centred on its local origin."""

    half_extents: np.ndarray = field(default_factory=lambda: np.ones(3))
    kind = "boxes"
    kernel = BOX
    usd_kind = "box"

    def __post_init__(self):
        super().__post_init__()
        h = vector(self.half_extents, 3, f"{self._label()} half_extents")
        if np.any(h <= 0):
            raise ValueError(f"{self._label()} half_extents must be > 0")
        object.__setattr__(self, "half_extents", h)

    def size_axis(self):
        return tuple(self.half_extents), (0.0, 0.0, 1.0)

    @classmethod
    def from_prim(cls, prim, position, rotation, scale, common):
        return cls(half_extents=np.asarray(prim.half_extents) * np.abs(scale), **common)
