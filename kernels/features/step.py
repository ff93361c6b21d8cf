"""The flags of the featured step and the Warp struct that carries its features' parameters.

:func:`feature_struct` builds, per precision and flag set, a struct with fields for the present
features only (the colliders' from their registered shapes,
:func:`~dftl_warp.kernels.features.collide.collider_fields`); the featured sweep
(``kernels/solvers/featured.py``) reads it, the host fills it
(:class:`~dftl_warp.features.step.FeatureStep`).
"""


import functools

import warp as wp

from .collide import collider_fields, collider_flags

#: the wind's curl noise is sampled at every NOISE_STRIDE-th particle of a strand and held between
NOISE_STRIDE = 8
#: the flags of the features that are not colliders (the colliders' are their registered shapes')
OTHER_FLAGS = ("drag", "wind", "wind_noise", "hair_hair")


def feature_flag_names() -> tuple:
    """Every known flag: the registered collider shapes', then the other features'."""
    return collider_flags() + OTHER_FLAGS


def check_flags(flags) -> frozenset:
    flags = frozenset(flags)
    known = feature_flag_names()
    unknown = flags - set(known)
    if unknown:
        raise ValueError(f"unknown feature flags {sorted(unknown)}; known: {', '.join(known)}")
    if ("wind" in flags or "wind_noise" in flags) and "drag" not in flags:
        raise ValueError("wind acts through air drag: the 'wind' flags need 'drag'")
    if "wind_noise" in flags and "wind" not in flags:
        raise ValueError("'wind_noise' needs 'wind'")
    return flags


@functools.cache
def feature_struct(scalar, flags: frozenset):
    """The Warp struct carrying the parameters of the features in ``flags`` (and nothing else)."""
    flags = check_flags(flags)
    vec3 = wp.types.vector(3, scalar)
    fields = collider_fields(scalar, flags)
    if "drag" in flags:
        fields["drag"] = wp.array(dtype=scalar)
    if "wind" in flags:
        fields["wind_velocity"] = wp.array(dtype=vec3)
    if "wind_noise" in flags:
        fields.update(
            wind_time=wp.array(dtype=scalar),
            noise_amplitude=scalar,
            noise_inv_scale=scalar,
            noise_frequency=scalar,
            noise_seed=int,
        )
    if "hair_hair" in flags:
        fields.update(
            grid_weights=wp.array(dtype=scalar),
            grid_lower=wp.array(dtype=scalar),
            grid_inv_h=scalar,
            grid_h=scalar,
            grid_nx=int,
            grid_ny=int,
            grid_nz=int,
            grid_density=wp.array3d(dtype=scalar),
            grid_mass=wp.array3d(dtype=scalar),
            grid_momentum=wp.array3d(dtype=vec3),
            grid_friction=scalar,
            grid_repulsion=scalar,
            grid_threshold=scalar,
        )
    name = "StepFeatures_" + ("f64_" if scalar == wp.float64 else "f32_") + "_".join(sorted(flags))
    cls = type(name, (), {"__annotations__": fields, "__module__": __name__, "__qualname__": name})
    return wp.struct(cls, module="unique")


