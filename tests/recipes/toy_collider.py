# dftl_warp/features/colliders/cylinder.py
"""A toy collider shape (the collider recipe of docs/architecture.md): a capped cylinder of
``radius`` (m) and ``half_height`` (m) along a local axis; USD: UsdGeomCylinder (``radius``,
``height``, ``axis``), its scale baked in as for a capsule."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...kernels.features.cylinder import CYLINDER
from .base import ColliderShape

_AXES = {"X": 0, "Y": 1, "Z": 2}


@dataclass(frozen=True, eq=False)
class Cylinder(ColliderShape):
    radius: float = 1.0
    half_height: float = 1.0
    axis: str = "Z"
    kind = "cylinders"
    kernel = CYLINDER
    usd_kind = "Cylinder"

    def __post_init__(self):
        super().__post_init__()
        if not float(self.radius) > 0 or not float(self.half_height) > 0:
            raise ValueError(f"{self._label()} needs radius > 0 and half_height > 0")

    def size_axis(self):
        axis = [0.0, 0.0, 0.0]
        axis[_AXES[self.axis]] = 1.0
        return (float(self.radius), float(self.half_height), 0.0), tuple(axis)

    @classmethod
    def from_prim(cls, prim, position, rotation, scale, common):
        a = prim.attributes
        axis = str(a.get("axis", "Z")).upper()
        s = np.abs(scale)
        across = np.delete(s, _AXES[axis]).max()
        return cls(radius=float(a.get("radius", 1.0)) * across,
                   half_height=0.5 * float(a.get("height", 2.0)) * s[_AXES[axis]], axis=axis, **common)
