"""Optional simulation features: colliders, root binding, drag and wind, hair-hair, shape retention.

The feature objects are re-exported here: ``from dftl_warp import features as F; F.Sphere(...)``.
"""

from .objects import (  # noqa: F401
    FEATURE_TYPES,
    SHAPE_KINDS,
    Box,
    Capsule,
    Colliders,
    Drag,
    HairHair,
    RootBinding,
    ShapeRetention,
    Sphere,
    TriangleMesh,
    Wind,
    check_features,
    feature_flags,
    find,
)
