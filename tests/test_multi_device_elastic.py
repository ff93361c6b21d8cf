"""Elastic strands on several devices (``--device A,B``) give the single-device result.

A prim with widths is an elastic rod by default; before, a groom split across devices ran as the plain
DFTL chain instead (with a warning), so one device and two gave different physics. Each strand's rod
is independent of the others', so the split run must equal the single-device run bit for bit, and to
the hair-hair grid's order of sums where the parts exchange a grid.
"""

from __future__ import annotations

import numpy as np
import pytest
from pxr import Gf, Sdf, UsdGeom, UsdPhysics
from usd_stages import add_curves, animated_xform, chain, new_stage, set_attr

from dftl_warp.cli import main
from dftl_warp.simulation.simulate import Simulation, SimulationOptions
from dftl_warp.simulation.split_elastic import SplitElasticSolver
from dftl_warp.usd.read import read_scene

SPACING = 0.8   # cm between vertices


def _stage(path, *, hair_hair=False, collider=True, wind=True):
    """Two prims of 0.5 mm hair (11 and 5 vertices, in cm) under a moving, turning head, a sphere
    some strands start inside, wind, and a clamp that turns with the head."""
    stage = new_stage(path, meters_per_unit=0.01, start=1, end=10)
    world = stage.GetPrimAtPath("/World")
    if wind:
        set_attr(world, "dftl:wind", "Float3", Gf.Vec3f(30.0, 0.0, 0.0))
    if hair_hair:
        set_attr(world, "dftl:hairHair", "Bool", True)
    animated_xform(stage, "/World/Head", translate={1: (500, 100, -300), 10: (506, 100, -300)},
                   rotate_y={1: 0.0, 10: 30.0})
    if collider:
        ball = UsdGeom.Sphere.Define(stage, "/World/Head/Ball")
        ball.CreateRadiusAttr(2.0)
        UsdGeom.XformCommonAPI(ball).SetTranslate(Gf.Vec3d(3.0, -6.0, 0.5))
        UsdPhysics.CollisionAPI.Apply(ball.GetPrim())
    rng = np.random.default_rng(3)
    for name, strands, vertices in (("Long", 9, 11), ("Short", 7, 5)):
        pts = [chain(vertices, SPACING, direction=(rng.uniform(-1, 1), -1.0, 0.2), origin=(k * 0.3, 0, 0))
               for k in range(strands)]
        curves = add_curves(stage, f"/World/Head/{name}", np.concatenate(pts), [vertices] * strands, widths=0.05,
                            bending=None)
        if wind:
            set_attr(curves.GetPrim(), "dftl:drag", "Float", 2.0 if name == "Long" else 0.5)
    stage.GetRootLayer().Save()
    return path


def _frames(path, device, frames=6, **options):
    scene = read_scene(str(path))
    sim = Simulation(scene, SimulationOptions(device=device, **options), 1)
    out = [[(p.copy(), v.copy()) for p, v in sim.samples()]]
    for _ in range(frames):
        sim.advance()
        out.append([(p.copy(), v.copy()) for p, v in sim.samples()])
    return sim, out


def _distance(a, b, item=0):
    return max(float(np.max(np.abs(p[item] - q[item]))) for fa, fb in zip(a, b) for p, q in zip(fa, fb))


def test_split_elastic_groom_with_colliders_and_wind_equals_single_device(tmp_path):
    path = _stage(tmp_path / "featured.usda")
    split, got = _frames(path, "cpu,cpu")
    single, want = _frames(path, "cpu")
    g, one = split.groups[0], single.groups[0]
    assert g.settings.solver == one.settings.solver == "elastic"
    assert isinstance(g.solver, SplitElasticSolver) and len(g.model.parts) == 2
    assert not any("plain DFTL chain" in w for w in split.scene.warnings), split.scene.warnings
    # the clean start moved hair out of the ball, and those strands rest where they were moved
    assert any("rest where they were moved out" in n for n in single.start_notes), single.start_notes
    assert split.start_notes == single.start_notes
    assert _distance(want, [want[0]] * len(want)) > 0.1     # the hair moves
    for frame_got, frame_want in zip(got, want):
        for (p, v), (q, w) in zip(frame_got, frame_want):
            assert p.tobytes() == q.tobytes() and v.tobytes() == w.tobytes()
    assert g.solver.energy(g.state) == pytest.approx(one.solver.energy(one.state), rel=1e-12)


def test_split_elastic_groom_with_hair_hair_equals_single_device(tmp_path):
    """The parts exchange the hair-hair grid every substep: float64, the result is the single-device
    one to the order of the splat's sums."""
    path = _stage(tmp_path / "hh.usda", hair_hair=True, wind=False)
    split, got = _frames(path, "cpu,cpu", precision="float64")
    single, want = _frames(path, "cpu", precision="float64")
    assert split.groups[0].solver.exchange is not None and split.groups[0].settings.solver == "elastic"
    length = 10 * SPACING
    assert _distance(got, want) < 1e-10 * length, _distance(got, want)
    assert _distance(got, want, 1) < 1e-7 * length


def test_split_elastic_checkpoint_resumes_exactly(tmp_path):
    from resume_check import assert_resumes_exactly

    path = _stage(tmp_path / "ckpt.usda", collider=False)
    assert_resumes_exactly(read_scene(str(path)), SimulationOptions(device="cpu,cpu", precision="float64"), 3, 3,
                           keys=("group0.tensions", "group0.frames", "group0.clamps"))


def test_split_elastic_notes_equal_single_device(tmp_path, capsys):
    """Strands standing beyond their buckling length are named alike on one device and two, and the
    command writes the single-device file."""
    path = tmp_path / "stand.usda"
    stage = new_stage(path, meters_per_unit=0.01, start=1, end=3)
    pts = [chain(21, 1.0, direction=(0.0, 1.0, 0.0), origin=(k * 0.5, 0, 0)) for k in range(6)]
    add_curves(stage, "/World/Stand", np.concatenate(pts), [21] * 6, widths=0.008, bending=None)
    stage.GetRootLayer().Save()
    notes = {}
    for device in ("cpu", "cpu,cpu"):
        out = tmp_path / device.replace(",", "_") / "o.usda"
        assert main(["simulate", str(path), "-o", str(out), "--device", device, "--quiet"]) == 0
        notes[device] = [line for line in capsys.readouterr().err.splitlines() if "device" not in line]
    assert any("unstable equilibrium" in line for line in notes["cpu"]), notes["cpu"]
    assert notes["cpu,cpu"] == notes["cpu"]
    text = [(tmp_path / d / "o.usda").read_text() for d in ("cpu", "cpu_cpu")]
    strip = [t[t.index("def "):] for t in text]   # past the header (provenance names the devices)
    assert strip[0] == strip[1]


@pytest.mark.parametrize("bending", [True, False])
def test_split_preroll_settles_as_on_one_device(tmp_path, bending):
    """--preroll on several devices: the parts settle as one groom (before, a split group skipped
    the preroll, with a note), elastic rods and DFTL chains alike."""
    path = _stage(tmp_path / "pre.usda", wind=False)
    if not bending:
        from pxr import Usd

        stage = Usd.Stage.Open(str(path))
        for name in ("Long", "Short"):
            set_attr(stage.GetPrimAtPath(f"/World/Head/{name}"), "dftl:bending", "Bool", False)
        stage.Save()
    split, got = _frames(path, "cpu,cpu", frames=2, preroll=0.5)
    single, want = _frames(path, "cpu", frames=2, preroll=0.5)
    assert split.start_notes == single.start_notes
    assert any(n.startswith("preroll:") and "settled" in n for n in split.start_notes), split.start_notes
    if not bending:   # chains sag as they settle; rods rest as authored (inverse statics)
        _, raw = _frames(path, "cpu", frames=0)
        assert _distance(want[:1], raw) > 0.1
    for frame_got, frame_want in zip(got, want):
        for (p, v), (q, w) in zip(frame_got, frame_want):
            assert p.tobytes() == q.tobytes() and v.tobytes() == w.tobytes()
