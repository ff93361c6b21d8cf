"""The velocity pass (``kernels/features/air_grid.py``): hair-hair, drag and wind applied before the
sweep, in their own kernel, give the motion the sweep gave when it applied them itself (CPU).

DFTL: the same arithmetic in the same order, so the trajectories are equal bit for bit. Elastic:
the pass hands the solve one acceleration where the kernel added two terms, so they agree to
round-off."""

from __future__ import annotations

import numpy as np
import pytest

import dftl_warp as dw
import dftl_warp.features.step as feature_step
from dftl_warp import features as F
from dftl_warp.kernels.features.air_grid import blocks_per_strand, split_flags, velocity_features_kernel

import warp as wp

FPS = 24.0
SUB = 4


def groom(strands: int = 24, n: int = 19):
    """Strands of ``n`` points (more than two blocks of the pass) hanging from a ring above a sphere
    of radius 0.1 m at the origin, two of them shorter (the pass's partial blocks)."""
    rng = np.random.default_rng(11)
    out, counts = [], []
    for s in range(strands):
        a = 2 * np.pi * s / strands
        root = np.array([0.06 * np.cos(a), 0.13, 0.06 * np.sin(a)])
        m = n if s % 7 else 9 + s % 5
        step = np.array([0.3 * np.cos(a), -1.0, 0.3 * np.sin(a)]) + 0.1 * rng.normal(size=3)
        step *= 0.006 / np.linalg.norm(step)
        out.append(root + np.arange(m)[:, None] * step)
        counts.append(m)
    return np.concatenate(out), counts


def features(collider: bool):
    fs = [F.HairHair(cell_size=0.01, friction=20.0, repulsion=5.0), F.Drag(1.5),
          F.Wind(velocity=(1.0, 0.0, 0.5), noise_amplitude=0.7, noise_scale=0.05)]
    if collider:
        fs.append(F.Colliders([F.Sphere(radius=0.1, friction=0.2)]))
    return fs


def run(monkeypatch, passed: bool, solver_name: str, collider: bool, correction: str = "prior",
        precision: str = "float32", frames: int = 6):
    monkeypatch.setattr(feature_step, "VELOCITY_PASS", passed)
    pts, counts = groom()
    model = dw.Model.from_strands(pts, counts, widths=1e-4, precision=precision, features=features(collider))
    if solver_name == "dftl":
        solver = dw.DFTLSolver(model, correction=correction, fused=False)
    else:
        solver = dw.make_solver(model, "elastic", correction=correction)
    assert (solver._features.velocity_form is not None) == passed
    state, control = solver.state(), model.control()
    for f in range(frames):
        control.features.set_frame_time(f / FPS, (f + 1) / FPS)
        solver.advance(state, control, 1.0 / (FPS * SUB), SUB)
    return (model.points_from_device(state.positions, relative=False),
            model.points_from_device(state.velocities, relative=False))


@pytest.mark.parametrize("collider,correction", [(False, "prior"), (False, "posterior"), (True, "prior"),
                                                 (True, "posterior")])
def test_dftl_with_the_pass_moves_as_the_featured_sweep_bit_for_bit(monkeypatch, collider, correction):
    """Without a collider the sweep after the pass is the bare step; with one, the colliders' sweep."""
    before = run(monkeypatch, False, "dftl", collider, correction)
    after = run(monkeypatch, True, "dftl", collider, correction)
    for a, b in zip(before, after):
        assert np.array_equal(a, b)
    assert np.abs(after[1]).max() > 0.05          # the wind did move the hair


@pytest.mark.parametrize("correction", ["prior", "posterior"])
def test_elastic_with_the_pass_moves_as_before_to_round_off(monkeypatch, correction):
    before = run(monkeypatch, False, "elastic", True, correction, precision="float64", frames=3)
    after = run(monkeypatch, True, "elastic", True, correction, precision="float64", frames=3)
    moved = np.abs(before[0] - groom()[0]).max()
    assert moved > 1e-3
    assert np.abs(before[0] - after[0]).max() < 1e-10 * max(moved, 1.0)
    assert np.abs(before[1] - after[1]).max() < 1e-8


def test_the_sweep_keeps_the_colliders_and_the_pass_the_rest():
    assert split_flags({"spheres", "hair_hair", "drag", "wind", "wind_noise"}) == (
        {"hair_hair", "drag", "wind", "wind_noise"}, {"spheres"})
    assert split_flags({"meshes"}) == (frozenset(), {"meshes"})
    assert [blocks_per_strand(n) for n in (0, 1, 2, 9, 10, 33)] == [0, 0, 1, 1, 2, 4]
    with pytest.raises(ValueError, match="subset"):
        velocity_features_kernel(wp.float32, wp.float32, frozenset({"spheres", "drag"}), "velocity")
    with pytest.raises(ValueError, match="form"):
        velocity_features_kernel(wp.float32, wp.float32, frozenset({"drag"}), "force")
