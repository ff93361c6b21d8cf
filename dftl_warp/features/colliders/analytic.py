"""Analytic collider shapes: :class:`Sphere`, :class:`Ellipsoid`, :class:`Capsule`, :class:`Box`.

Their geometry travels in the common per-collider ``size`` and ``axis`` vectors (m); their
surfaces are the signed-distance functions of ``kernels/features/analytic.py``. USD:
UsdGeomSphere, UsdGeomCapsule, UsdGeomCube, their scale baked in:

- a Sphere under a uniform scale stays a sphere; under a non-uniform one it is the ellipsoid it is
  (:class:`Ellipsoid`, exact signed distance);
- a Cube takes its scale per axis (exact);
- a Capsule under a uniform scale is exact; otherwise it becomes the smallest capsule of our kind
  that contains the scaled one (radius: the largest scale across the axis; the core segment grown
  so that the tips reach the scaled tips), with a warning naming the prim and the largest surface
  offset;
- shear in a transform is dropped (the nearest rotation is kept) with a warning (``usd.py``).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ...kernels.features.analytic import BOX, CAPSULE, ELLIPSOID, SPHERE
from ..base import vector
from .base import ColliderShape, warn_approximation

#: scales that differ by less than this (relative) are uniform
UNIFORM = 1.0e-6


def _length(value, what: str, positive: bool = True) -> float:
    """``value`` as a finite float > 0 (``positive``) or >= 0; ValueError naming ``what``."""
    if isinstance(value, (str, bytes, bool, np.bool_)):   # "1" was kept as a string, True taken as 1
        raise ValueError(f"{what} must be a finite number, got {value!r}")
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{what} must be a finite number, got {value!r}") from None
    if not np.isfinite(v) or not (v > 0 if positive else v >= 0):
        raise ValueError(f"{what} must be {'>' if positive else '>='} 0 and finite, got {value!r}")
    return v


def _uniform(values) -> bool:
    a = np.abs(np.asarray(values, dtype=np.float64))
    return float(a.max() - a.min()) <= UNIFORM * float(a.max())

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
        _length(self.radius, f"{self._label()} radius")

    def size_axis(self):
        return (float(self.radius), 0.0, 0.0), (0.0, 0.0, 1.0)

    @classmethod
    def from_prim(cls, prim, position, rotation, scale, common):
        if _uniform(scale):
            return cls(radius=prim.radius * np.abs(scale).max(), **common)
        return Ellipsoid(radii=prim.radius * np.abs(scale), **common)


@dataclass(frozen=True, eq=False)
class Ellipsoid(ColliderShape):
    """An ellipsoid of semi-axes ``radii`` (3,) (m) along its local x, y, z, centred on its local
    origin (a USD Sphere under a non-uniform scale). Its signed distance is exact."""

    radii: np.ndarray = field(default_factory=lambda: np.ones(3))
    kind = "ellipsoids"
    kernel = ELLIPSOID
    usd_kind = ""  # made from a scaled USD Sphere by Sphere.from_prim

    def __post_init__(self):
        super().__post_init__()
        r = vector(self.radii, 3, f"{self._label()} radii")
        if np.any(r <= 0):
            raise ValueError(f"{self._label()} radii must be > 0")
        object.__setattr__(self, "radii", r)

    def size_axis(self):
        return tuple(self.radii), (0.0, 0.0, 1.0)


@dataclass(frozen=True, eq=False)
class Capsule(ColliderShape):
    """A capsule: points within ``radius`` (m) of the segment of half length ``half_height`` (m)
    along the local ``axis``: "X", "Y" or "Z" (upper case, the UsdGeomCapsule tokens; anything else
    is refused) or a vector of 3 finite numbers, not zero (normalised)."""

    radius: float = 1.0
    half_height: float = 1.0
    axis: object = "Z"
    kind = "capsules"
    kernel = CAPSULE
    usd_kind = "capsule"

    def __post_init__(self):
        super().__post_init__()
        _length(self.radius, f"{self._label()} radius")
        _length(self.half_height, f"{self._label()} half_height", positive=False)
        if isinstance(self.axis, str):
            if self.axis not in _AXES:
                raise ValueError(f"{self._label()} axis must be \"X\", \"Y\" or \"Z\" (or a vector), got {self.axis!r}")
        else:
            axis = vector(self.axis, 3, f"{self._label()} axis")
            if np.linalg.norm(axis) < 1e-12:
                raise ValueError(f"{self._label()} axis must not be the zero vector, got {self.axis!r}")

    def size_axis(self):
        axis = np.asarray(_AXES[self.axis] if isinstance(self.axis, str) else self.axis, dtype=np.float64)
        axis = vector(axis, 3, f"{self._label()} axis")
        return (float(self.radius), float(self.half_height), 0.0), tuple(axis / np.linalg.norm(axis))

    @classmethod
    def from_prim(cls, prim, position, rotation, scale, common):
        a = np.abs(scale)
        axis = _AXIS_INDEX.get(str(prim.axis).upper(), 2)
        radius = prim.radius * np.delete(a, axis).max()
        half = 0.5 * prim.height * a[axis]
        if _uniform(a):
            return cls(radius=radius, half_height=half, axis="XYZ"[axis], **common)
        # the scaled capsule: an (elliptic) cylinder of half length `half` with half-ellipsoid caps
        # of semi-axes radius x scale. Ours contains it: the largest radius across, and the core
        # grown so that the tips reach the scaled tips when the axis is scaled more than across.
        tip = prim.radius * a[axis]
        grown = half + max(0.0, tip - radius)
        offset = _capsule_offset(prim.radius, 0.5 * prim.height, axis, a, radius, grown)
        warn_approximation(common.get("name", ""), (
            f"capsule under the non-uniform scale {tuple(float(v) for v in scale)}: simulated as the "
            f"enclosing capsule (radius {radius:g}, half height {grown:g}); its surface lies up to "
            f"{offset:g} outside the authored one"))
        return cls(radius=radius, half_height=grown, axis="XYZ"[axis], **common)


def _capsule_offset(radius, half_height, axis, scale, new_radius, new_half) -> float:
    """How far (m) the surface of the capsule (``new_radius``, ``new_half`` along ``axis``) lies
    outside that of the authored one (``radius``, ``half_height``) under ``scale``: the largest
    depth of the scaled surface's points below the new surface (measured on a fine sampling)."""
    k = 4000
    i = np.arange(k) + 0.5
    z = 1.0 - 2.0 * i / k
    ring = np.sqrt(1.0 - z * z)
    phi = np.pi * (1.0 + 5.0 ** 0.5) * i
    sphere = np.stack([ring * np.cos(phi), ring * np.sin(phi), z], axis=1) * radius
    sphere[:, 2] += np.sign(sphere[:, 2]) * half_height                 # the two caps
    t, h = np.meshgrid(np.linspace(0.0, 2.0 * np.pi, 181), np.linspace(-half_height, half_height, 41))
    side = np.stack([radius * np.cos(t).ravel(), radius * np.sin(t).ravel(), h.ravel()], axis=1)
    local = np.concatenate([sphere, side])                             # axis along z
    order = [j for j in range(3) if j != axis] + [axis]
    world = np.empty_like(local)
    world[:, order] = local
    world *= scale
    along = np.clip(world[:, axis], -new_half, new_half)
    across = world.copy()
    across[:, axis] -= along
    return float(max(0.0, (new_radius - np.linalg.norm(across, axis=1)).max()))


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
