"""A particle does not push itself through a grid splatted substeps ago (CPU).

The grid's density gradient a particle feels leaves out its own contribution. With
``splat_interval`` > 1 that contribution sits where the particle was splatted (its position then,
``(interval - 1) dt / 2`` ahead along its velocity), not where it is now; leaving out the one at
its present position left a gradient toward where it had been, and the repulsion pushed it on
along its motion: the lone pendulums below strayed 1.5 cm in 1 s at interval 5, 3.5 cm at 10."""

from __future__ import annotations

import numpy as np
import pytest

import dftl_warp as dw
from dftl_warp import features as F


def swing(features, frames=24, substeps=10, precision="float64"):
    """Pendulums of one free particle each, 5 cm below their roots, started sideways at 1 m/s,
    the roots 50 cm apart: each particle is alone in its part of a 1 cm grid."""
    roots = np.stack([np.arange(4) * 0.5, np.zeros(4), np.zeros(4)], 1)
    pts = np.concatenate([[r, r + [0.0, -0.05, 0.0]] for r in roots])
    model = dw.Model.from_strands(pts, [2] * 4, precision=precision, features=features)
    solver = dw.DFTLSolver(model, fused=False)
    state, control = solver.state(), model.control()
    v = np.zeros((8, 3))
    v[1::2, 0] = 1.0
    state.velocities.assign(model.points_to_device(v, relative=False).astype(state.velocities.numpy().dtype))
    for _ in range(frames):
        solver.advance(state, control, 1.0 / (24 * substeps), substeps)
    return model.points_from_device(state.positions, relative=False)


@pytest.mark.parametrize("interval", [1, 5, 10])
def test_an_isolated_particle_feels_no_repulsion_of_its_own(interval):
    free = swing([])
    grid = swing([F.HairHair(cell_size=0.01, friction=0.0, repulsion=50.0, splat_interval=interval)])
    assert np.abs(free[1::2] - free[0::2]).max() > 0.0      # they swing
    assert np.abs(grid - free).max() < 1e-12, np.abs(grid - free).max()
