"""Bounding boxes of point arrays.

numpy reduces an (N, 3) array along axis 0 one strided column element at a time: on the 2-core CPU
VM ``points.min(0), points.max(0)`` of 50,800 points took 4.0 ms, the same reductions over the
contiguous transposed copy 0.16 ms (2026-11-27). The deforming body's bounds are taken every frame
(``features/colliders``), and a 1M-strand groom's (33M points) at set-up and in the renderer.
"""

from __future__ import annotations

import numpy as np


def box(points) -> tuple[np.ndarray, np.ndarray]:
    """The lower and upper corners (3,) of ``points`` (N, 3) (N > 0), in their dtype: the same
    values as ``points.min(0), points.max(0)`` (NaN included), in a fraction of their time."""
    columns = np.ascontiguousarray(np.asarray(points).reshape(-1, 3).T)
    return columns.min(axis=1), columns.max(axis=1)
