"""The repulsion of a grid rebuilt every few substeps pushes with the particles' present density (CPU).

The grid's density gradient a particle feels leaves out its own contribution. When the whole grid
was rebuilt only every ``splat_interval`` substeps, that contribution sat where the particle was
splatted, not where it is: the lone pendulums below strayed 1.5 cm in 1 s at interval 5 and 3.5 cm
at 10, pushed on along their motion. And a density substeps old acts on the groom as a delayed
spring, which feeds the motion it opposes (a dense groom moved twice as fast at interval 5). Now
the density alone is splatted every substep between the full rebuilds; only the momentum (the
friction's grid velocity) waits for them."""

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
    state.write("velocities", model.points_to_device(v, relative=False))
    for _ in range(frames):
        solver.advance(state, control, 1.0 / (24 * substeps), substeps)
    return model.points_from_device(state.positions, relative=False)


@pytest.mark.parametrize("interval", [1, 5, 10])
def test_an_isolated_particle_feels_no_repulsion_of_its_own(interval):
    free = swing([])
    grid = swing([F.HairHair(cell_size=0.01, friction=0.0, repulsion=50.0, splat_interval=interval)])
    assert np.abs(free[1::2] - free[0::2]).max() > 0.0      # they swing
    assert np.abs(grid - free).max() < 1e-12, np.abs(grid - free).max()


@pytest.mark.parametrize("interval", [1, 5])
def test_the_repulsion_reads_the_particles_present_density_at_every_substep(interval):
    """Between full rebuilds the density alone is splatted again every substep, so the repulsion
    never pushes with a density older than the particles (a density up to 4 substeps old acted as
    a delayed spring and doubled the speed of a dense groom, docs/features.md); the momentum and
    its own density ("mass") stay those of the last rebuild."""
    import warp as wp

    from dftl_warp.kernels.features.grid_strands import grid_splat_strands_kernel

    rng = np.random.default_rng(2)
    roots = rng.uniform(-0.02, 0.02, (30, 3))
    pts = np.concatenate([r + np.outer(np.arange(8), [0.0, -0.004, 0.0]) for r in roots])
    model = dw.Model.from_strands(pts, [8] * 30, features=[F.HairHair(cell_size=0.01, splat_interval=interval)])
    solver = dw.DFTLSolver(model, fused=False)
    state, control = solver.state(), model.control()
    v = np.zeros((240, 3))
    v[:, 0] = rng.uniform(-1.0, 1.0, 240)
    state.write("velocities", model.points_to_device(v, relative=False))
    dt = 1.0 / 240
    solver.step(state, state, control, dt, 1.0 / 3)   # a rebuild (the frame's first substep) ...
    solver.step(state, state, control, dt, 2.0 / 3)   # ... then substeps without one (interval 5)
    before = wp.clone(state.positions)                # what the third substep starts from
    solver.step(state, state, control, dt, 3.0 / 3)
    grid = solver._features._grid
    g = grid.arrays
    fresh = wp.zeros_like(g["density"])
    scratch = wp.zeros_like(g["momentum"])
    wp.launch(grid_splat_strands_kernel(model.scalar), dim=model.num_strands,
              inputs=[model.strand_base, model.strand_stride, model.strand_count, before, state.velocities,
                      g["weights"], g["lower"], 1.0 / grid.cell, 0.0, *grid.shape], outputs=[fresh, scratch])
    scale = np.abs(fresh.numpy()).max()   # hair volume fraction at the densest node
    assert scale > 0.0
    assert np.abs(g["density"].numpy() - fresh.numpy()).max() < 1e-5 * scale
    if interval > 1:
        assert g["mass"].shape == g["density"].shape
        # the rebuild's, not the present's
        assert np.abs(g["mass"].numpy() - fresh.numpy()).max() > 1e-3 * scale
