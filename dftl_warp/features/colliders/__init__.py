"""Colliders: shapes the hair stays outside of (:class:`Colliders` of registered shapes).

Add a collider shape (three files): its host module here (a :class:`ColliderShape` subclass:
parameters, ``size_axis``, ``usd_kind`` -- a USD prim type name -- and ``from_prim``, which maps the
prim's ``attributes`` as the USD reader read them; optional device data), its kernel module in
``kernels/features/`` (its signed distance or collide function, as a
:class:`~dftl_warp.kernels.features.collide.ColliderKernel`), and its import and entry in the
registration line below. ``tests/test_recipes.py`` adds a toy cylinder this way.
"""

from .analytic import Box, Capsule, Sphere
from .analytic import Ellipsoid  # made by Sphere.from_prim under a non-uniform scale
from .base import ATTRIBUTES, SHAPES, ColliderApproximationWarning, ColliderShape, Colliders, register_shape, shape_kinds
from .device import ColliderControl, ColliderData, build, fixed_bytes, inverse_poses
from .mesh import MeshColliders, TriangleMesh
from .usd import from_scene, shape_from_prim, split_matrix, update_from_scene

# the registered shapes, in device order (one line per shape)
for _shape in (Sphere, Capsule, Box, TriangleMesh):
    register_shape(_shape)
del _shape
register_shape(Ellipsoid)  # no USD type of its own: a scaled Sphere prim

#: kernel flags of the registered shapes, in device order
SHAPE_KINDS = shape_kinds()

__all__ = ["ATTRIBUTES", "SHAPES", "SHAPE_KINDS", "ColliderApproximationWarning", "ColliderShape", "Colliders", "register_shape", "shape_kinds",
           "ColliderControl", "ColliderData", "build", "fixed_bytes", "inverse_poses", "MeshColliders",
           "from_scene", "shape_from_prim", "split_matrix", "update_from_scene",
           *(cls.__name__ for cls in SHAPES.values())]
