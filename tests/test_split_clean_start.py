"""A groom split over devices is moved out of its colliders as one: the same strands, the same rounds.

Before, every part ran the push-out on its own: a part with hair only resting on a collider (none
inside) was left as it was while one device pushed that hair to the contact distance too, and the
rounds stopped when the part's own deepest particle was out, not the groom's; the split run then
started (and after a preroll, ended) from a different state than the single-device run.
"""

from __future__ import annotations

import numpy as np
import pytest
from pxr import Gf, UsdGeom, UsdPhysics
from usd_stages import add_curves, chain, new_stage

from dftl_warp.simulation.simulate import Simulation, SimulationOptions
from dftl_warp.usd.read import read_scene

RADIUS = 0.025   # hair radius, cm


def _stage(path):
    """A ball of radius 2 cm; strand 0 hangs past it within the hair's radius of its surface (touching,
    not inside), strand 1 hangs through it. Split over two devices, each part holds one strand."""
    stage = new_stage(path, meters_per_unit=0.01, start=1, end=3)
    ball = UsdGeom.Sphere.Define(stage, "/World/Ball")
    ball.CreateRadiusAttr(2.0)
    UsdGeom.XformCommonAPI(ball).SetTranslate(Gf.Vec3d(0.0, -6.0, 0.0))
    UsdPhysics.CollisionAPI.Apply(ball.GetPrim())
    pts = [chain(11, 0.8, direction=(0.0, -1.0, 0.0), origin=(x, -0.4, 0.0)) for x in (2.0 + 0.4 * RADIUS, 1.0)]
    add_curves(stage, "/World/Hair", np.concatenate(pts), [11, 11], widths=2 * RADIUS)
    stage.GetRootLayer().Save()
    return path


@pytest.mark.parametrize("preroll", [0.0, 0.1])
def test_split_clean_start_equals_single_device(tmp_path, preroll):
    path = _stage(tmp_path / "ball.usda")
    out = {}
    for device in ("cpu", "cpu,cpu"):
        sim = Simulation(read_scene(str(path)), SimulationOptions(device=device, preroll=preroll), 1)
        assert len(sim.groups[0].devices) == len(device.split(","))
        out[device] = sim.samples()[0][0].copy(), sim.start_notes
    (single, notes), (split, split_notes) = out["cpu"], out["cpu,cpu"]
    assert any("5 of 20 free particles" in n for n in notes), notes
    # one device pushes the resting strand to the contact distance as well
    touching = single[:11] - np.asarray(chain(11, 0.8, direction=(0.0, -1.0, 0.0),
                                              origin=(2.0 + 0.4 * RADIUS, -0.4, 0.0)))
    assert preroll or np.abs(touching).max() > 0.1 * RADIUS
    assert split_notes == notes
    assert split.tobytes() == single.tobytes(), np.abs(split - single).max()


def test_clean_start_lines_name_their_prims_where_groups_are_several(tmp_path):
    """Prims simulated in different groups (here DFTL chains and an elastic rod) each get
    their clean start's and preroll's lines; before, the lines were alike and named no prim."""
    path = _stage(tmp_path / "ball.usda")
    from pxr import Usd

    stage = Usd.Stage.Open(str(path))
    add_curves(stage, "/World/Rod", chain(11, 0.8, direction=(0.0, -1.0, 0.0), origin=(0.5, -0.4, 0.0)), [11],
               widths=2 * RADIUS, bending=True)
    stage.Save()
    sim = Simulation(read_scene(str(path)), SimulationOptions(device="cpu", preroll=0.1), 1)
    assert len(sim.groups) == 2
    inside = [n for n in sim.start_notes if "started inside a collider" in n]
    prerolls = [n for n in sim.start_notes if n.startswith("preroll: ")]
    assert sorted(n.split(": ")[1] for n in inside) == ["/World/Hair", "/World/Rod"], inside
    assert sorted(n.split(": ")[1] for n in prerolls) == ["/World/Hair", "/World/Rod"], prerolls
    single = Simulation(read_scene(str(_stage(tmp_path / "one.usda"))), SimulationOptions(device="cpu"), 1)
    assert any(n.startswith("clean start: 5 of 20 free particles") for n in single.start_notes), single.start_notes


def test_a_group_of_one_strand_on_several_devices_with_a_collider(tmp_path):
    """A one-strand group on three devices fits in one part; with a collider its clean start crashed
    ('SplitModel' object has no attribute 'strand_count'). It now runs as on one device."""
    path = tmp_path / "one.usda"
    stage = new_stage(path, meters_per_unit=0.01, start=1, end=3)
    ball = UsdGeom.Sphere.Define(stage, "/World/Ball")
    ball.CreateRadiusAttr(2.0)
    UsdGeom.XformCommonAPI(ball).SetTranslate(Gf.Vec3d(0.0, -6.0, 0.0))
    UsdPhysics.CollisionAPI.Apply(ball.GetPrim())
    add_curves(stage, "/World/Rod", chain(11, 0.8, direction=(0.0, -1.0, 0.0), origin=(1.0, -0.4, 0.0)), [11],
               widths=2 * RADIUS, bending=True)
    add_curves(stage, "/World/Chains", np.concatenate([chain(8, 0.8, direction=(0.0, -1.0, 0.0), origin=(x, 0.0, 0.0))
                                                       for x in (0.5, 3.0)]), [8, 8])
    stage.GetRootLayer().Save()
    out = {}
    for device in ("cpu", "cpu,cpu,cpu"):
        sim = Simulation(read_scene(str(path)), SimulationOptions(device=device, preroll=0.05), 1)
        frames = [sim.samples()]
        for _ in range(2):
            sim.advance()
            frames.append(sim.samples())
        out[device] = sim.start_notes, [p.tobytes() for f in frames for p, _ in f]
    assert any("/World/Rod: " in n and "started inside" in n for n in out["cpu"][0]), out["cpu"][0]
    assert out["cpu,cpu,cpu"] == out["cpu"]
