"""The collider shape base class, the shape registry and :class:`Colliders`.

A collider shape is a host class (parameters, USD mapping, device geometry) deriving from
:class:`ColliderShape` plus its kernel side (a
:class:`~dftl_warp.kernels.features.collide.ColliderKernel`: flag, struct fields, collide
function), joined by :func:`register_shape`. Registration order is the device order of the
colliders and the order the sweep tests them in.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np

from ...kernels.features.collide import ColliderKernel, register_collider_kernel
from ...usd.colliders import accept_collider_type
from ..base import nonnegative, unit_quaternion, vector

#: name -> (type, where: "scene", "curves", "both" or "collider", description)
ATTRIBUTES = {
    "dftl:collisionIterations": (int, "scene", "collide-and-restore rounds per particle (>= 1, default 2)"),
    "dftl:collisionSdf": (bool, "collider", "mesh colliders: true through a signed distance field, false exact "
                                            "queries; unset: the field from 20000 triangles on"),
    "dftl:collisionSdfCellSize": (float, "collider", "cell of a mesh collider's signed distance field"),
}

#: kernel flag -> shape class, in registration (device) order
SHAPES: dict = {}


class ColliderApproximationWarning(UserWarning):
    """A collider prim is simulated as an approximation of what was authored (the message names the
    prim, what is approximated and by how much)."""


def warn_approximation(name: str, message: str) -> None:
    """Warn that collider ``name`` (a prim path) is approximated: ``message`` says how. The USD
    mapping (:func:`~dftl_warp.features.colliders.usd.from_scene`) collects these into the scene's
    warnings, once per prim and message."""
    warnings.warn(f"{name or 'collider'}: {message}", ColliderApproximationWarning, stacklevel=3)


@dataclass(frozen=True, eq=False)
class ColliderShape:
    """A collider at rest: ``position`` (3,) m and ``rotation`` (x, y, z, w) of its local frame
    in the world, Coulomb ``friction`` (>= 0), and a ``name`` for messages (the USD prim path).

    Subclasses set ``kind`` (their kernel flag, e.g. ``"spheres"``), ``kernel`` (their
    :class:`~dftl_warp.kernels.features.collide.ColliderKernel`) and ``usd_kind`` (the
    :class:`~dftl_warp.usd.scene.ColliderPrim` kind they are made from: a built-in kind, or a USD
    prim type name such as ``"Cylinder"``, whose prims the reader then reads generically into
    ``prim.attributes``), and implement
    :meth:`size_axis` and :meth:`from_prim`; shapes with data of their own on the device (meshes)
    also :meth:`make_device_data`."""

    #: world position of the collider's local origin at rest, m
    position: np.ndarray = field(default_factory=lambda: np.zeros(3))
    #: world rotation at rest, quaternion (x, y, z, w): a non-unit one is normalised (it names
    #: the same rotation, as in the poses of ``set_collider_poses``); a zero or non-finite one is
    #: refused
    rotation: np.ndarray = field(default_factory=lambda: np.array([0.0, 0.0, 0.0, 1.0]))
    #: Coulomb friction coefficient (dimensionless, >= 0)
    friction: float = 0.3
    #: a name for messages (e.g. the USD prim path)
    name: str = ""

    kind: ClassVar[str] = ""
    kernel: ClassVar[ColliderKernel | None] = None
    usd_kind: ClassVar[str] = ""

    def __post_init__(self):
        object.__setattr__(self, "position", vector(self.position, 3, f"{self._label()} position"))
        object.__setattr__(self, "rotation", unit_quaternion(self.rotation, f"{self._label()} rotation"))
        object.__setattr__(self, "friction", nonnegative(self.friction, f"{self._label()} friction"))

    def _label(self):
        return f"{type(self).__name__.lower()} {self.name!r}" if self.name else type(self).__name__.lower()

    def size_axis(self):
        """``(size (3,), axis (3,))``: the shape's geometry in the common per-collider device
        vectors (m; unit axis), as its signed-distance function reads them."""
        return (0.0, 0.0, 0.0), (0.0, 0.0, 1.0)

    @classmethod
    def from_prim(cls, prim, position, rotation, scale, common: dict):
        """The shape of a USD collider ``prim`` (:class:`~dftl_warp.usd.scene.ColliderPrim`) whose
        transform splits into ``position``, ``rotation`` and per-axis ``scale`` (baked into the
        geometry); ``common``: position, rotation, friction and name keywords."""
        raise NotImplementedError

    @classmethod
    def make_device_data(cls, model, shapes: dict, num_colliders: int):
        """Device data of this kind beyond the common per-collider vectors, made per Control:
        an object with ``fill_struct(st)`` (and whatever per-frame setters the kind offers), or
        None. ``shapes``: device collider index -> user index and shape, of this kind."""
        return None

    def fixed_bytes(self) -> int:
        """Device bytes of the shape's own data beyond the common per-collider vectors."""
        return 0


def register_shape(cls):
    """Register collider shape class ``cls`` (its kernel side too); returns it."""
    if not (isinstance(cls, type) and issubclass(cls, ColliderShape)) or not cls.kind or cls.kernel is None:
        raise ValueError(f"{cls!r} is not a collider shape with a kind and a kernel")
    if cls.kernel.flag != cls.kind:
        raise ValueError(f"{cls.__name__}: kind {cls.kind!r} but kernel flag {cls.kernel.flag!r}")
    known = SHAPES.get(cls.kind)
    if known is not None and known is not cls:
        raise ValueError(f"collider kind {cls.kind!r} is registered twice")
    register_collider_kernel(cls.kernel)
    if cls.usd_kind:
        accept_collider_type(cls.usd_kind)  # the USD reader reads prims of this type for it
    SHAPES[cls.kind] = cls
    return cls


def shape_kinds() -> tuple:
    """Kernel flags of the registered shapes, in device order."""
    return tuple(SHAPES)


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
        if isinstance(self.shapes, tuple(SHAPES.values())):   # one shape: "'Sphere' object is not iterable"
            raise TypeError(f"shapes must be a list of shapes, got one {type(self.shapes).__name__}: "
                            f"Colliders([{type(self.shapes).__name__}(...)])")
        shapes = tuple(self.shapes)
        for i, s in enumerate(shapes):
            if not isinstance(s, tuple(SHAPES.values())):
                names = ", ".join(c.__name__ for c in SHAPES.values())
                raise ValueError(f"collider {i} is a {type(s).__name__}, not one of {names}")
        object.__setattr__(self, "shapes", shapes)
        if int(self.iterations) < 1:
            raise ValueError(f"collider iterations must be >= 1, got {self.iterations}")
        if not shapes:
            warnings.warn("Colliders has no shapes: the hair collides with nothing (give it a shape, or leave "
                          "the feature out)", UserWarning, stacklevel=3)

    @property
    def flags(self):
        return frozenset(s.kind for s in self.shapes)
