"""core.bounds.box: the same corners as numpy's axis-0 min and max (min and max are exact, so
equal bit for bit), NaN included, in the points' dtype."""

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from dftl_warp.core.bounds import box


@settings(max_examples=60, deadline=None)
@given(arrays(st.sampled_from([np.float32, np.float64]), st.tuples(st.integers(1, 50), st.just(3)),
              elements=st.floats(-1e6, 1e6, allow_nan=False, width=32)))
def test_box_is_the_axis_zero_min_and_max(points):
    lo, hi = box(points)
    assert lo.dtype == points.dtype and lo.shape == (3,)
    assert np.array_equal(lo, points.min(0)) and np.array_equal(hi, points.max(0))


def test_box_propagates_nan_and_takes_flat_or_non_contiguous_input():
    p = np.arange(12.0).reshape(4, 3)
    p[2, 1] = np.nan
    lo, hi = box(p)
    assert np.isnan(lo[1]) and np.isnan(hi[1]) and lo[0] == 0.0 and hi[2] == 11.0
    wide = np.arange(24.0).reshape(4, 6)[:, ::2]          # a strided view
    assert np.array_equal(box(wide)[1], wide.max(0))
    assert np.array_equal(box(np.arange(6.0))[0], [0.0, 1.0, 2.0])   # flat: read as (N, 3)
