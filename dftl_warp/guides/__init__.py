"""Guides and render strands (issue 22): simulate a few guides, deform the dense groom from them.

- :mod:`.select`: :func:`select_guides` picks guide strands from a dense groom (``"fps"`` or ``"kmeans"``);
- :mod:`.binding`: :func:`bind` / :func:`bind_groom` compute, once at rest, each render strand's
  ``k`` nearest guides, RBF weights (a partition of unity) and rest offsets in the guides' local
  frames (:mod:`.frames`); :func:`deform_reference` applies a binding in numpy;
- :mod:`.deform`: :class:`GuideDeformer` applies a binding on the device each frame (Warp, float32).

See ``docs/guides.md``.
"""

from .binding import MAX_K, Binding, bind, bind_groom, deform_reference, guide_points_of
from .select import METHODS, select_guides

__all__ = ["MAX_K", "METHODS", "Binding", "GuideDeformer", "bind", "bind_groom", "deform_reference",
           "guide_points_of", "select_guides"]


def __getattr__(name):
    if name == "GuideDeformer":  # loads Warp only when asked
        from .deform import GuideDeformer

        return GuideDeformer
    raise AttributeError(f"module 'dftl_warp.guides' has no attribute {name!r}")
