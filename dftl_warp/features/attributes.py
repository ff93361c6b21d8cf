"""Moved: the ``dftl:`` attributes now live with their features and are composed in
:mod:`dftl_warp.features.scene`; import them from :mod:`dftl_warp.features`. This alias goes
once no module imports it."""

from .scene import ATTRIBUTES, features_from_attributes  # noqa: F401
