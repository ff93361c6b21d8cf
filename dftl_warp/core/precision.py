"""Floating-point precision of a simulation: ``"float32"`` (default) or ``"float64"``."""

from __future__ import annotations

import numpy as np
import warp as wp

PRECISIONS = ("float32", "float64")


def scalar_type(precision: str):
    """Warp scalar type for ``precision``."""
    if precision == "float32":
        return wp.float32
    if precision == "float64":
        return wp.float64
    raise ValueError(f"unknown precision {precision!r}; choose float32 or float64")


def vec3_type(precision: str):
    """Warp 3-vector type for ``precision``."""
    return wp.types.vector(3, scalar_type(precision))


def numpy_type(precision: str):
    """numpy dtype for ``precision``."""
    scalar_type(precision)
    return np.dtype(precision)
