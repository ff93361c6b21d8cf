"""Fused substeps (state on chip for a whole frame) give the unfused path's results exactly."""

import numpy as np
import pytest

import dftl_warp as dw
from dftl_warp.solvers.fused_runs import fused_capacity, fused_runs
from fused_frames import random_groom, simulate

LENGTHS = [1, 2, 7, 8, 9, 13]  # not multiples of the capacity blocks (8), except one exact fit


def groom(rng):
    return random_groom(rng, LENGTHS)


def run(pts, counts, *, fused, precision, correction, layout):
    x, v, _, _ = simulate(pts, counts, fused=fused, precision=precision, correction=correction, layout=layout,
                          substeps=5, frames=6)
    return x, v


@pytest.mark.parametrize("precision,correction", [("float64", "prior"), ("float64", "posterior"),
                                                  ("float32", "prior")])
@pytest.mark.parametrize("layout", ["strand-major", "particle-major", "interleaved"])
def test_fused_equals_unfused(precision, correction, layout, rng):
    pts, counts = groom(rng)
    x0, v0 = run(pts, counts, fused=False, precision=precision, correction=correction, layout=layout)
    x1, v1 = run(pts, counts, fused=True, precision=precision, correction=correction, layout=layout)
    assert np.isfinite(x0).all()
    assert np.array_equal(x0, x1)
    assert np.array_equal(v0, v1)


def test_fused_runs_group_strands_by_capacity():
    counts = np.array([3, 8, 9, 16, 17, 5])
    runs = fused_runs(counts, dw.Model.from_strands(np.zeros((58, 3)), counts).scalar, "prior")
    assert [(first, size) for _, first, size in runs] == [(0, 1), (1, 1), (2, 1), (3, 1), (4, 1), (5, 1)]
    assert [fused_capacity(c) for c in counts] == [8, 8, 16, 16, 24, 8]


def test_fused_refuses_long_strands_only_in_the_posterior_form():
    model = dw.Model.from_strands(np.c_[np.arange(100.0), np.zeros(100), np.zeros(100)], [100])
    assert not dw.DFTLSolver(model).fused  # the CPU steps substep by substep unless asked
    with pytest.raises(ValueError, match="at most 64"):
        dw.DFTLSolver(model, correction="posterior", fused=True)
    assert dw.DFTLSolver(model, fused=True).fused  # prior form: pipelined, any length


def test_fused_is_chosen_only_where_measured_faster():
    from dftl_warp.solvers.fused_runs import PIPELINED_PAYS, fused_pays

    assert not fused_pays(8, 1, "float32")  # one substep per frame never gains
    assert fused_pays(16, 2, "float32") and fused_pays(8, 8, "float64")
    assert fused_pays(32, 2, "float32") and not fused_pays(32, 1, "float32")  # x1.65 at 2 (H200)
    assert fused_pays(32, 4, "float64") and not fused_pays(32, 2, "float64")  # x0.69 at 2, x1.07 at 4
    # longer strands: the pipelined kernel (prior form only)
    assert fused_pays(40, PIPELINED_PAYS, "float32") and not fused_pays(40, PIPELINED_PAYS - 1, "float32")
    assert fused_pays(128, 8, "float64") and not fused_pays(40, 16, "float32", "posterior")


def test_fused_equals_unfused_past_the_on_chip_rest_lengths(rng):
    """Capacities above REST_ON_CHIP_MAX re-read rest lengths every substep: same results. Only
    the posterior form keeps such strands on chip (the prior form pipelines them)."""
    from dftl_warp.kernels.solvers.fused import REST_ON_CHIP_MAX

    n = REST_ON_CHIP_MAX + 5  # capacity REST_ON_CHIP_MAX + 8, not filled
    steps = rng.normal(size=(n, 3))
    steps /= np.linalg.norm(steps, axis=1, keepdims=True)
    pts, counts = np.cumsum(steps * 0.02, axis=0), np.array([n])
    assert fused_capacity(n) > REST_ON_CHIP_MAX
    x0, v0, _, _ = simulate(pts, counts, fused=False, precision="float64", correction="posterior",
                            layout="strand-major", substeps=5, frames=6)
    x1, v1, _, solver = simulate(pts, counts, fused=True, precision="float64", correction="posterior",
                                 layout="strand-major", substeps=5, frames=6)
    assert [(first, size) for _, first, size in solver._fused_runs] == [(0, 1)] and not solver._pipelined_runs
    assert np.array_equal(x0, x1) and np.array_equal(v0, v1)


@pytest.mark.parametrize("layout", ["strand-major", "interleaved"])
def test_fused_with_rest_lengths_in_shared_rows_equals_unfused(layout, rng):
    """float32 strands of 25-32 vertices take the capacity-32 kernel, whose rest lengths live in a
    shared-memory row (kernels/fused.py, REST_IN_SHARED; on the CPU a static row per thread)."""
    import warp as wp

    from dftl_warp.kernels.solvers.fused import REST_IN_SHARED

    assert (wp.float32, 32) in REST_IN_SHARED
    pts, counts = random_groom(rng, [32, 25, 32, 30, 2, 32])
    x0, v0, c0, _ = simulate(pts, counts, fused=False, precision="float32", layout=layout, substeps=4, frames=3)
    x1, v1, c1, solver = simulate(pts, counts, fused=True, precision="float32", layout=layout, substeps=4, frames=3)
    assert any(kernel.key.find("fused") >= 0 for kernel, _, _ in solver._fused_runs)
    assert {fused_capacity(c) for c in counts} == {8, 32}
    assert np.array_equal(x0, x1) and np.array_equal(v0, v1) and np.array_equal(c0, c1)
