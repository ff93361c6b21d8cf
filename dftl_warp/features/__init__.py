"""Optional simulation features: colliders, root binding, drag and wind, hair-hair.

A scene turns a feature on by giving its object to the model
(``Model.from_strands(points, counts, widths=..., features=[...])``); the solver then compiles a
step specialized to exactly those features (``kernels/solvers/featured.py``), and a scene without
any runs the bare DFTL kernel. Units are SI (m, s, m/s, 1/s), or stage units consistently.

One module per feature, each with its parameters, device data, per-frame control and USD mapping:

- :mod:`.colliders`: :class:`Colliders` of registered shapes (:class:`Sphere`, :class:`Capsule`,
  :class:`Ellipsoid`, :class:`Box`, :class:`TriangleMesh`), each with a pose the Control animates per frame and a
  Coulomb friction;
- :mod:`.binding`: :class:`RootBinding`, roots as barycentric points on a deforming mesh;
- :mod:`.air`: :class:`Drag` (1/s) and :class:`Wind` (m/s, keyframed, optional curl noise);
- :mod:`.hair_hair`: :class:`HairHair`, grid-based friction and repulsion (Petrovic et al. 2005);

then :mod:`.step` composes them (flags, Model data, ``control.features``, the featured step) and
:mod:`.scene` maps a USD Scene to them. ``from dftl_warp import features as F; F.Sphere(...)``.
"""

from .air import Drag, Wind
from .base import find
from .binding import RootBinding
from .colliders import (SHAPE_KINDS, SHAPES, Box, Capsule, ColliderShape, Colliders, Ellipsoid, Sphere, TriangleMesh,
                        register_shape)
from .hair_hair import HairHair, hair_hair_extent
from .scene import (
    ATTRIBUTES,
    feature_names,
    features_from_attributes,
    group_features,
    update_frame,
    widths_per_point,
)
from .colliders.usd import split_matrix
from .step import (
    FEATURE_TYPES,
    FeatureControl,
    FeatureStep,
    ModelFeatures,
    build,
    check_features,
    feature_flags,
    memory_estimate,
)
from ..core.state import install_feature_hooks

install_feature_hooks(build=build, control=FeatureControl)

__all__ = [
    "Colliders", "ColliderShape", "Sphere", "Ellipsoid", "Capsule", "Box", "TriangleMesh", "SHAPES", "SHAPE_KINDS",
    "register_shape", "RootBinding", "Drag", "Wind", "HairHair",
    "FEATURE_TYPES", "check_features", "feature_flags", "find",
    "ModelFeatures", "FeatureControl", "FeatureStep", "build", "memory_estimate", "hair_hair_extent",
    "ATTRIBUTES", "features_from_attributes", "group_features", "update_frame", "feature_names",
    "widths_per_point", "split_matrix",
]
