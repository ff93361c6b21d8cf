import numpy as np
import pytest
import warp as wp

wp.config.log_level = wp.LOG_WARNING
wp.init()


def chain(n, spacing=0.1, direction=(1.0, 0.0, 0.0), origin=(0.0, 0.0, 0.0)):
    """Points of a straight chain of ``n`` particles, root first."""
    d = np.asarray(direction, dtype=np.float64)
    return np.asarray(origin, dtype=np.float64) + np.arange(n)[:, None] * spacing * d


def segment_lengths(points, counts):
    """Lengths of every segment of concatenated strands (points (..., N, 3))."""
    starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
    d = np.linalg.norm(np.diff(points, axis=-2), axis=-1)
    keep = np.ones(points.shape[-2] - 1, dtype=bool)
    keep[starts[1:] - 1] = False  # segments that would join two strands
    return d[..., keep]


@pytest.fixture
def rng():
    return np.random.default_rng(1234)
