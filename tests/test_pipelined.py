"""Pipelined substeps (one lane per substep, strands of any length) give the unfused path's results
exactly. On the CPU the solver runs the serial form of the pipeline (one thread per lane group),
which shares its per-particle functions and schedule with the CUDA kernel; the CUDA kernel's warp
shuffles are checked against the unfused path on the GPU by scripts/check_fused_equal.py and
scripts/bench.py (fused section)."""

import numpy as np
import pytest
import warp as wp

import dftl_warp as dw
from dftl_warp.kernels.solvers.pipelined import pipelined_serial_kernel
from dftl_warp.solvers.fused_runs import ON_CHIP_PRIOR_VERTICES, pipelined_runs
from fused_frames import random_groom, simulate, swing_roots

# longer than the on-chip limit (33, 37, 100), one run of several strands (40 x 3), mixed with
# short strands that stay on chip (1, 2, 9)
LENGTHS = [1, 33, 40, 2, 40, 37, 9, 100, 40]


def run(pts, counts, *, fused, precision, layout, substeps, frames=4):
    return simulate(pts, counts, fused=fused, precision=precision, layout=layout, substeps=substeps, frames=frames)


@pytest.mark.parametrize("precision", ["float64", "float32"])
@pytest.mark.parametrize("layout", ["strand-major", "particle-major", "interleaved"])
@pytest.mark.parametrize("substeps", [1, 2, 3, 8])
def test_pipelined_equals_unfused(precision, layout, substeps, rng):
    pts, counts = random_groom(rng, LENGTHS)
    x0, v0, c0, _ = run(pts, counts, fused=False, precision=precision, layout=layout, substeps=substeps)
    x1, v1, c1, solver = run(pts, counts, fused=True, precision=precision, layout=layout, substeps=substeps)
    assert solver._pipelined_runs, "the long strands must take the pipelined kernel"
    assert np.isfinite(x0).all()
    assert np.array_equal(x0, x1)
    assert np.array_equal(v0, v1)
    assert np.array_equal(c0, c1)


@pytest.mark.parametrize("interleave", [1, 3])
def test_pipelined_runs_cover_exactly_the_long_strands(interleave):
    counts = np.array(LENGTHS + [40] * 60)
    model = dw.Model.from_strands(np.zeros((int(counts.sum()), 3)), counts, layout="particle-major",
                                  interleave=interleave)
    runs = pipelined_runs(model.layout, ON_CHIP_PRIOR_VERTICES)
    assert sorted((r.count, r.strands) for r in runs) == [(33, 1), (37, 1), (40, 63), (100, 1)]
    for r in runs:  # the kernel computes slots from (base, strand_step, chunk, stride)
        assert r.chunk == 32 * interleave
        for k in range(r.strands):
            s = r.first + k
            assert model.layout.strand_base[s] == r.base + ((k // 32) * r.chunk + k % 32) * r.strand_step
            assert model.layout.strand_stride[s] == r.stride
        assert 1 <= r.groups <= r.strands


@pytest.mark.parametrize("groups", [1, 2, 5, 7])
def test_streams_of_several_strands_per_group(groups, rng):
    """Lane groups that stream several strands one after another (and groups with one strand
    fewer than others) give the unfused result."""
    pts, counts = random_groom(rng, [45] * 7)
    ref = run(pts, counts, fused=False, precision="float64", layout="particle-major", substeps=4, frames=2)
    model = dw.Model.from_strands(pts, counts, precision="float64", layout="particle-major")
    solver = dw.DFTLSolver(model, fused=False, gravity=(0.0, -9.81, 0.0))
    state, control = solver.state(), model.control()
    roots = pts[np.concatenate([[0], np.cumsum(counts)[:-1]])]
    K = 4
    vectors = wp.empty((groups * K, 6), dtype=model.vec3, device="cpu")
    scalars = wp.empty((groups * K, 2), dtype=model.scalar, device="cpu")
    for frame in range(2):
        swing_roots(control, roots, frame)
        wp.launch(pipelined_serial_kernel(model.scalar, control.root_path_curved), dim=groups, device="cpu",
                  inputs=[0, 7, groups, 45, 0, 1, 32, 7, control.root_start, control.root_end,
                          control.root_deviation_start, control.root_deviation_end, model.rest_lengths,
                          solver.gravity, 1 / 240, solver.damping, K, vectors, scalars,
                          state.positions, state.velocities, state.corrections])
    assert np.array_equal(model.points_from_device(state.positions), ref[0])
    assert np.array_equal(model.points_from_device(state.velocities, relative=False), ref[1])
