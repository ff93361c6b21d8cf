"""Moved: a Scene's features are now composed in :mod:`dftl_warp.features.scene` from each
feature's USD mapping; import them from :mod:`dftl_warp.features`. This alias goes once no
module imports it."""

from .colliders.usd import split_matrix  # noqa: F401
from .scene import feature_names, group_features, update_frame, widths_per_point  # noqa: F401
