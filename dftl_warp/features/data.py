"""Moved: the features' device data now live with each feature and are composed in
:mod:`dftl_warp.features.step`; import them from :mod:`dftl_warp.features`. This alias goes
once no module imports it."""

from .hair_hair import hair_hair_extent  # noqa: F401
from .shape import rest_frames  # noqa: F401
from .step import FeatureControl, FeatureStep, ModelFeatures, build, memory_estimate  # noqa: F401
