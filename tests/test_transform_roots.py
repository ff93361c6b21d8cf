"""Roots moved by their prims' transforms get their frame's targets on the device
(dftl_warp/simulation/transform_roots.py): the same C1 path as the host path computes from the
frames' world roots, and the same clamp ghosts and rotations for elastic strands."""

from __future__ import annotations

import numpy as np
import pytest
from test_multi_device_elastic import _frames, _stage

import dftl_warp.simulation.transform_roots as transform_roots
from dftl_warp.usd.scene import transform_points


def _host_path(monkeypatch):
    monkeypatch.setattr(transform_roots, "drive", lambda *args: False)


@pytest.mark.parametrize("device", ["cpu", "cpu,cpu"])
def test_device_root_paths_equal_the_host_paths(tmp_path, monkeypatch, device):
    """Elastic rods (clamps turning with the head) and DFTL chains under a moving, turning head:
    float64 positions as the host path's to round-off, float32 bit for bit."""
    path = _stage(tmp_path / "head.usda")
    for precision, tol in (("float32", 0.0), ("float64", 1e-12)):
        sim, got = _frames(path, device, precision=precision)
        assert sim.transform_roots, "the device path was not taken"
        with monkeypatch.context() as m:
            _host_path(m)
            host_sim, want = _frames(path, device, precision=precision)
        assert not host_sim.transform_roots
        for fa, fb in zip(got, want):
            for (p, v), (q, w) in zip(fa, fb):
                assert np.abs(p - q).max() <= tol * 10.0, (precision, np.abs(p - q).max())
                assert np.abs(v - w).max() <= 1e-6 if precision == "float64" else np.array_equal(v, w)


def test_device_roots_sit_at_the_transformed_authored_roots(tmp_path):
    """Physics, not the host path: at every frame the simulated roots are the authored local roots
    through the prim's matrix at that frame (written in local space: the authored roots)."""
    path = _stage(tmp_path / "head.usda", collider=False, wind=False)
    sim, frames = _frames(path, "cpu", precision="float64")
    for k, curve in enumerate(sim.scene.curves):
        for samples in frames:
            points = samples[k][0]
            np.testing.assert_allclose(points[curve.root_indices], curve.points[curve.root_indices], atol=1e-9)
    g = sim.groups[0]
    world = transform_points(sim._matrix(g.members[0], sim.frame), sim._roots_local[g.members[0]])
    starts = np.r_[0, np.cumsum(g.model.counts)[:-1]][:world.shape[0]]
    roots = g.model.points_from_device(g.state.positions)[starts]
    np.testing.assert_allclose(roots, world, atol=1e-9)
