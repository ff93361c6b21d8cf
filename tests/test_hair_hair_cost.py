"""The cheaper hair-hair grid (issue 20): rebuilt every ``splat_interval`` substeps, splatted one
thread per strand, bounds one thread per strand. Checked against today's pipeline (bit for bit at
an interval of 1), against conservation (the per-strand splat), and against the physics: a
converged run (the interval's error is below the time-discretisation error the step already makes)."""

import numpy as np
import pytest
import warp as wp

import dftl_warp as dw
from dftl_warp import cli
from dftl_warp import features as F
from dftl_warp.kernels.features.grid import grid_bounds_kernel, grid_reset_kernel, grid_splat_kernel

G = (0.0, -9.81, 0.0)
FPS = 24
SEGMENT = 0.01  # m


def head_groom(strands, vertices=32, seed=0):
    """Strands rooted on the upper half of a 10 cm head, combed outward and down (1 cm segments):
    the hair falls and piles up on itself in the first frames."""
    rng = np.random.default_rng(seed)
    d = rng.normal(size=(strands, 3))
    d[:, 1] = np.abs(d[:, 1])
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    out = d + np.array([0.0, -0.5, 0.0])
    out /= np.linalg.norm(out, axis=1, keepdims=True)
    pts = 0.102 * d[:, None] + np.arange(vertices)[None, :, None] * SEGMENT * out[:, None]
    return pts.reshape(-1, 3), np.full(strands, vertices)


def fall(pts, counts, frames, substeps, **hair_hair):
    """Positions (input order, m) after each of ``frames`` frames of ``substeps`` substeps."""
    model = dw.Model.from_strands(pts, counts, features=[F.HairHair(**hair_hair)])
    solver = dw.DFTLSolver(model, gravity=G)
    state, control = solver.state(), model.control()
    out = []
    for _ in range(frames):
        solver.advance(state, control, 1.0 / FPS / substeps, substeps)
        out.append(model.points_from_device(state.positions))
    return np.array(out)


def test_interval_1_is_todays_pipeline_bit_for_bit():
    """Every substep: lower corner (one thread per particle), clear, splat, sweep, as before."""
    pts, counts = head_groom(40, 12)
    feats = [F.HairHair(cell_size=0.02, friction=3.0, repulsion=20.0, splat="particles")]
    substeps, dt = 5, 1.0 / FPS / 5
    runs = []
    for by_hand in (False, True):
        model = dw.Model.from_strands(pts, counts, features=feats)
        solver = dw.DFTLSolver(model, gravity=G)
        state, control = solver.state(), model.control()
        step = solver._features
        g, s = step.grid, model.scalar
        for _ in range(3):
            if not by_hand:
                solver.advance(state, control, dt, substeps)
                continue
            for k in range(substeps):
                alpha = float(np.float32(k + 1) / np.float32(substeps))
                wp.launch(grid_reset_kernel(s), dim=1, device=model.device, outputs=[g["lower"]])
                wp.launch(grid_bounds_kernel(s), dim=model.num_slots, device=model.device, inputs=[state.positions],
                          outputs=[g["lower"]])
                g["density"].zero_()
                g["momentum"].zero_()
                wp.launch(grid_splat_kernel(s), dim=model.num_slots, device=model.device,
                          inputs=[state.positions, state.velocities, g["weights"], g["lower"], 1.0 / 0.02, 0.0,
                                  *step._grid.shape], outputs=[g["density"], g["momentum"]])
                step.sweep(state, state, control, solver.feature_head(control, dt, alpha))
        runs.append([a.numpy().copy() for a in (state.positions, state.velocities, state.corrections)])
    for a, b in zip(*runs):
        assert np.array_equal(a, b)
    assert np.abs(runs[0][1]).max() > 0.1  # the hair moved


@pytest.mark.parametrize("interval,rebuilds", [(1, 20), (3, 8), (10, 2), (25, 2)])
def test_the_grid_is_rebuilt_every_interval_substeps_of_each_frame(interval, rebuilds):
    pts, counts = head_groom(4, 6)
    model = dw.Model.from_strands(pts, counts, features=[F.HairHair(cell_size=0.02, splat_interval=interval)])
    solver = dw.DFTLSolver(model, gravity=G)
    state, control = solver.state(), model.control()
    grid = solver._features._grid
    leads = []
    splat = grid.splat
    grid.splat = lambda x, v, lead=0.0: (leads.append(lead), splat(x, v, lead))
    dt = 1.0 / FPS / 10
    for _ in range(2):
        solver.advance(state, control, dt, 10)
    assert len(leads) == rebuilds
    # splatted (interval - 1) dt / 2 ahead: centred on the substeps that sample it
    assert leads == pytest.approx([0.5 * (interval - 1) * dt] * rebuilds)


def test_strand_splat_is_the_particle_splat_and_conserves_particles_and_momentum():
    """Trilinear weights sum to one: the grid holds the hair volume fraction of every particle
    inside it once, and the sum of their velocities weighted by it; the per-strand splat adds the
    same terms in another order."""
    pts, counts = head_groom(60, 16, seed=2)
    rng = np.random.default_rng(5)
    velocities = rng.normal(size=pts.shape)
    grids = {}
    for splat in ("particles", "strands"):
        # a grid smaller than the hair: strands leave it and come back (nothing splatted outside)
        hh = F.HairHair(cell_size=0.015, splat=splat, extent=(0.3, 0.2, 0.3))
        model = dw.Model.from_strands(pts, counts, precision="float64", features=[hh])
        solver = dw.DFTLSolver(model, gravity=G)
        state = solver.state()
        state.write("velocities", model.points_to_device(velocities, relative=False))
        grid = solver._features._grid
        grid.bounds(state.positions)
        grid.splat(state.positions, state.velocities)
        grids[splat] = {name: a.numpy() for name, a in grid.arrays.items()}
        x = model.points_from_device(state.positions, relative=False)
        lower = grids[splat]["lower"]
        cell = (x - lower) / 0.015 + 1.0
        inside = np.all((cell >= 0) & (cell < np.array(grid.shape) - 1), axis=1)
        assert 0.2 * len(x) < inside.sum() < len(x)  # some hair outside the grid
        weights = grids[splat]["weights"][model.layout.slot_of_point]   # input order
        assert weights.min() > 0.0
        assert grids[splat]["density"].sum() == pytest.approx(weights[inside].sum(), rel=1e-12)
        momentum = (weights[:, None] * velocities)[inside].sum(0)
        np.testing.assert_allclose(grids[splat]["momentum"].sum(axis=(0, 1, 2)), momentum,
                                   rtol=1e-10, atol=1e-10 * np.abs(momentum).max())
    a, b = grids["particles"], grids["strands"]
    assert np.array_equal(a["lower"], b["lower"])
    np.testing.assert_allclose(b["density"], a["density"], rtol=1e-13, atol=1e-13)
    np.testing.assert_allclose(b["momentum"], a["momentum"], rtol=1e-13, atol=1e-12)


def rms(a, b):
    """RMS position difference over the particles, per frame, as a fraction of the strand length."""
    return np.sqrt(np.mean(np.sum((a - b) ** 2, axis=-1), axis=-1)) / (31 * SEGMENT)


def test_interval_error_is_below_the_steps_own_time_discretisation_error():
    """A grid rebuilt every k substeps is up to (k - 1) dt / 2 old or young: a lag of the same kind
    (of order dt) as the step's explicit use of the last substep's positions for every force. So the
    interval's change to the motion must stay below the error the step already makes at this dt
    against a converged run (8 x the substeps; its distance to 4 x shows it converged), while the
    hair-hair effect itself is many times larger. The groom falls and piles onto itself (hair moving
    at metres per second), the default cell (4 segments), the repulsion of all the density
    (threshold 0: it acts from the first substep, the stronger interaction)."""
    pts, counts = head_groom(50)
    substeps, frames, cell = 10, 6, 4 * SEGMENT
    today = fall(pts, counts, frames, substeps, cell_size=cell, threshold=0.0)
    converged = fall(pts, counts, frames, 8 * substeps, cell_size=cell, threshold=0.0)
    finer = fall(pts, counts, frames, 4 * substeps, cell_size=cell, threshold=0.0)
    without = fall(pts, counts, frames, substeps, cell_size=cell, friction=0.0, repulsion=0.0)
    at = [2, 5]  # t = 3/24 s and 6/24 s (before the pile becomes chaotic)
    discretisation = rms(today, converged)[at]
    assert (rms(finer, converged)[at] < 0.35 * discretisation).all()  # first order: the reference converged
    for k in (2, 5):
        moved = fall(pts, counts, frames, substeps, cell_size=cell, splat_interval=k, threshold=0.0)
        interval = rms(moved, today)[at]
        assert (interval > 0).all()
        assert (interval < discretisation).all(), (k, interval, discretisation)
        assert (rms(without, today)[at] > 5 * interval).all()  # hair-hair matters here


def test_bad_splat_interval_is_refused(tmp_path, capsys):
    from pxr import Sdf, UsdPhysics
    from usd_stages import add_curves, chain, new_stage

    from dftl_warp.features import features_from_attributes

    for bad in (0, -2, 2.5, True, "3"):
        with pytest.raises(ValueError, match="splat_interval must be an integer >= 1"):
            F.HairHair(cell_size=0.01, splat_interval=bad)
    with pytest.raises(ValueError, match="splat must be one of particles, strands"):
        F.HairHair(cell_size=0.01, splat="cells")
    hh = features_from_attributes({"dftl:hairHair": True, "dftl:hairHairSplatInterval": 4}, [{}], [1],
                                  mean_segment=0.01)[0]
    assert hh.splat_interval == 4 and hh.splat == "strands"  # the default splat
    stage = new_stage(tmp_path / "in.usda")
    scene = UsdPhysics.Scene.Define(stage, "/World/Physics").GetPrim()
    scene.CreateAttribute("dftl:hairHair", Sdf.ValueTypeNames.Bool, custom=True).Set(True)
    scene.CreateAttribute("dftl:hairHairSplatInterval", Sdf.ValueTypeNames.Int, custom=True).Set(0)
    add_curves(stage, "/World/Hair", chain(5, 0.01), [5])
    stage.Save()
    out = tmp_path / "out.usdc"
    assert cli.main(["simulate", str(tmp_path / "in.usda"), "-o", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "/World/Physics: dftl:hairHairSplatInterval = 0: must be >= 1" in err[0], err
    assert not out.exists()
