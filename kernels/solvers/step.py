"""The DFTL step kernel for a scene: the bare kernel, or one specialized to the scene's features."""

from .featured import featured_step_kernel
from .ftl import CORRECTIONS, bare_step_kernel


def step_kernel(scalar, correction: str, features=frozenset(), scale_pushes: bool = True):
    """The DFTL step kernel for ``scalar`` precision, ``correction`` form and feature flags.

    The empty feature set (a gravity-only scene) gets the bare kernel
    (:func:`~dftl_warp.kernels.solvers.ftl.bare_step_kernel`), the very same object whatever way
    it is asked for; a non-empty one gets a kernel specialized to exactly those features
    (:func:`~dftl_warp.kernels.solvers.featured.featured_step_kernel`). ``scale_pushes``:
    :func:`~dftl_warp.kernels.solvers.ftl.carried_func`.
    """
    features = frozenset(features)
    if not features:
        return bare_step_kernel(scalar, correction, scale_pushes)
    if correction not in CORRECTIONS:
        raise ValueError(f"unknown correction {correction!r}")
    return featured_step_kernel(scalar, correction, features, scale_pushes)
