"""simulation.group.Group: one class for a group on one device or split over several; and the
collider-shape registry (a toy shape added the way docs/architecture.md's recipe says)."""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np
import warp as wp

import dftl_warp as dw
from batch_stages import groom_stage
from dftl_warp import features as F
from dftl_warp.core.layout import strand_offsets
from dftl_warp.kernels.features.collide import analytic_collider
from dftl_warp.simulation.group import Group
from dftl_warp.simulation.multi_device import SplitModel, SplitState
from dftl_warp.simulation.simulate import Simulation, SimulationOptions
from dftl_warp.usd.read import read_scene


def test_strand_offsets():
    assert strand_offsets([3, 1, 2]).tolist() == [0, 3, 4]
    assert strand_offsets([3, 1, 2], with_end=True).tolist() == [0, 3, 4, 6]
    assert strand_offsets([]).tolist() == []


def test_one_group_class_for_one_or_several_devices(tmp_path):
    path = groom_stage(tmp_path / "g.usda", strands=6, vertices=5, end=3)
    scene = read_scene(str(path))
    one = Simulation(scene, SimulationOptions(device="cpu"), 1)
    two = Simulation(scene, SimulationOptions(device="cpu,cpu"), 1)
    (g1,), (g2,) = one.groups, two.groups
    assert type(g1) is Group and type(g2) is Group
    assert isinstance(g1.model, dw.Model) and isinstance(g1.state, dw.State) and isinstance(g1.control, dw.Control)
    assert isinstance(g2.model, SplitModel) and len(g2.model.parts) == 2 and g2.devices == ["cpu", "cpu"]
    assert g1.num_points == g2.num_points and g1.point_ranges == [(0, g1.num_points)]
    for _ in range(2):
        one.advance()
        two.advance()
    for (p, v), (q, w) in zip(one.samples(), two.samples()):
        assert p.tobytes() == q.tobytes() and v.tobytes() == w.tobytes()


def test_split_state_writes_through_state_write():
    """A split state's assign goes through State.write: an interleaved part keeps its other fields."""
    pts = np.stack([np.zeros(8), -np.arange(8) * 0.01, np.zeros(8)], 1)
    models = [dw.Model.from_strands(pts[:4], [4], layout="particle-major", interleave=3),
              dw.Model.from_strands(pts[4:], [4])]
    states = [m.state() for m in models]
    split = SplitState(states, models)
    velocities = np.concatenate([m.points_to_device(np.full((4, 3), 1.5), relative=False) for m in models])
    split.velocities.assign(velocities)
    for m, s in zip(models, states):
        assert np.array_equal(m.points_from_device(s.velocities, relative=False), np.full((4, 3), 1.5))
        rest = (pts[:4] if m is models[0] else pts[4:]).astype(np.float32)
        assert np.array_equal(m.points_from_device(s.positions), rest)


# -- a toy collider shape: its host class, its kernel (an SDF), one registration ---------------------


@functools.cache
def _ground_sdf(scalar):
    vec3 = wp.types.vector(3, scalar)

    @wp.func
    def ground_sdf(q: vec3, size: vec3, axis: vec3):
        return q[1], vec3(scalar(0.0), scalar(1.0), scalar(0.0))

    return ground_sdf


@dataclass(frozen=True, eq=False)
class _Ground(F.ColliderShape):
    """The half space y < 0 of its local frame."""

    kind = "toy_grounds"
    kernel = analytic_collider("toy_grounds", "collide_toy_ground", _ground_sdf)
    usd_kind = "toy_ground"


def test_a_registered_toy_shape_collides():
    from dftl_warp.kernels.features.collide import COLLIDER_KERNELS

    F.register_shape(_Ground)
    try:
        _toy_ground_run()
    finally:  # leave the registry as the package made it
        F.SHAPES.pop("toy_grounds", None)
        COLLIDER_KERNELS.pop("toy_grounds", None)


def _toy_ground_run():
    assert "toy_grounds" in F.SHAPES
    n = 6
    pts = np.stack([np.zeros(n), 0.05 - np.arange(n) * 0.0, np.arange(n) * 0.01], 1)
    model = dw.Model.from_strands(pts, [n], widths=0.002, features=[F.Colliders([_Ground(friction=0.0)])])
    assert model.feature_flags == {"toy_grounds"}
    solver = dw.DFTLSolver(model, gravity=(0.0, -9.81, 0.0))
    state, control = solver.state(), model.control()
    for _ in range(24):
        solver.advance(state, control, 1 / 240, 10)
    y = model.points_from_device(state.positions)[:, 1]
    assert y.min() > 0.001 - 1e-6  # the hair radius above the ground, not through it
