"""simulate --device A,B,...: strands split across devices give exactly the single-device result."""

from __future__ import annotations

import numpy as np
import pytest

from batch_stages import groom_stage, layer_content
from dftl_warp.cli import main
from dftl_warp.batch.jobs import Job
from dftl_warp.simulation.group import Group
from dftl_warp.simulation.multi_device import SplitModel, split_strands
from dftl_warp.batch.checkpoint import CheckpointPolicy, run_job
from dftl_warp.simulation.simulate import Simulation, SimulationOptions, simulate_usd
from dftl_warp.usd.read import read_scene
from pxr import Sdf, Usd
from usd_stages import add_curves, animated_xform, chain, new_stage


@pytest.mark.parametrize("counts, parts", [
    ([4] * 10, 2), ([4] * 10, 3), ([1, 50, 2, 2, 2, 2], 2), ([3, 3], 5), ([7], 4), ([5] * 1000, 8)])
def test_split_strands_covers_every_strand_once_in_order(counts, parts):
    ranges = split_strands(counts, parts)
    assert ranges[0][0] == 0 and ranges[-1][1] == len(counts)
    assert all(a < b for a, b in ranges) and all(r[1] == s[0] for r, s in zip(ranges, ranges[1:]))
    assert len(ranges) == min(parts, len(counts))
    if len(set(counts)) == 1 and len(counts) % parts == 0:
        assert {b - a for a, b in ranges} == {len(counts) // parts}


@pytest.fixture(scope="module")
def far_stage(tmp_path_factory):
    """Two prims of different strand lengths, far from the origin (so the Model origin is not
    zero), under a moving, turning transform; float32 results depend on the origin."""
    path = tmp_path_factory.mktemp("split") / "far.usda"
    stage = new_stage(path, meters_per_unit=0.01, start=1, end=12)
    animated_xform(stage, "/World/Head", translate={1: (5000, 100, -3000), 12: (5010, 100, -3000)},
                   rotate_y={1: 0.0, 12: 40.0})
    rng = np.random.default_rng(7)
    for name, strands, vertices in (("Long", 37, 11), ("Short", 25, 4)):
        pts = [chain(vertices, 0.8, direction=(rng.uniform(-1, 1), -1.0, 0.2), origin=(k * 0.3, 0, 0))
               for k in range(strands)]
        add_curves(stage, f"/World/Head/{name}", np.concatenate(pts), [vertices] * strands)
    stage.GetRootLayer().Save()
    return path


def _frames(stage, device, frames=8, **options):
    scene = read_scene(str(stage))
    sim = Simulation(scene, SimulationOptions(device=device, **options), 1)

    def samples():  # copies: on the CPU, samples() may return views of buffers reused next frame
        return [(p.copy(), v.copy()) for p, v in sim.samples()]

    out = [samples()]
    for _ in range(frames):
        sim.advance()
        out.append(samples())
    return sim, out


@pytest.mark.parametrize("devices, options", [
    ("cpu,cpu", {}), ("cpu,cpu,cpu", {"correction": "posterior", "substeps": 3}),
    ("cpu,cpu", {"precision": "float64", "solver": "ftl"})])
def test_split_equals_single_device(far_stage, devices, options):
    split, got = _frames(far_stage, devices, **options)
    single, want = _frames(far_stage, "cpu", **options)
    assert all(isinstance(g, Group) and isinstance(g.model, SplitModel) for g in split.groups)
    assert any(len(g.model.parts) == len(devices.split(",")) for g in split.groups)
    assert np.any(split.groups[0].model.origin != 0.0)
    for frame_got, frame_want in zip(got, want):
        for (p, v), (q, w) in zip(frame_got, frame_want):
            assert p.tobytes() == q.tobytes() and v.tobytes() == w.tobytes()
    assert split.num_strands == single.num_strands and split.num_points == single.num_points


def test_split_through_simulate_and_resumable_batch(tmp_path, far_stage):
    """The simulate path writes the same USD, and a split job checkpoints and resumes."""
    for name in ("single", "split", "batch"):
        (tmp_path / name).mkdir()
    simulate_usd(str(far_stage), str(tmp_path / "single" / "o.usdc"), device="cpu")
    simulate_usd(str(far_stage), str(tmp_path / "split" / "o.usdc"), device="cpu,cpu")
    assert layer_content(tmp_path / "split" / "o.usdc") == layer_content(tmp_path / "single" / "o.usdc")

    job = Job(index=1, name="far", input=str(far_stage), output=str(tmp_path / "batch" / "o.usdc"))

    def stop(event):
        if event["event"] == "frames" and event["done"] == 7:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        run_job(job, "cpu,cpu", CheckpointPolicy(every_frames=3), stop)
    resumed = run_job(job, "cpu,cpu", CheckpointPolicy(every_frames=3))
    assert resumed.status == "done" and resumed.resumed_from == 6
    assert layer_content(tmp_path / "batch" / "o.usdc") == layer_content(tmp_path / "single" / "o.usdc")


def test_unknown_device_in_the_list_is_one_line(tmp_path, far_stage, capsys):
    code = main(["simulate", str(far_stage), "-o", str(tmp_path / "o.usdc"), "--device", "cpu,cuda:9", "--quiet"])
    err = capsys.readouterr().err.strip()
    assert code == 2 and err.startswith("dftl-warp: error: --device cuda:9: not available here")
    assert "\n" not in err and not (tmp_path / "o.usdc").exists()


def test_more_devices_than_strands(tmp_path):
    path = groom_stage(tmp_path / "two.usda", strands=2, vertices=5, end=4)
    split, got = _frames(path, "cpu,cpu,cpu,cpu", frames=3)
    _, want = _frames(path, "cpu", frames=3)
    assert len(split.groups[0].model.parts) == 2
    for frame_got, frame_want in zip(got, want):
        for (p, v), (q, w) in zip(frame_got, frame_want):
            assert np.array_equal(p, q) and np.array_equal(v, w)


def _featured_stage(path, hair_hair=False):
    """The far stage plus a moving sphere collider, per-prim drag, wind."""
    from pxr import Gf, UsdGeom, UsdPhysics

    stage = new_stage(path, meters_per_unit=0.01, start=1, end=10)
    world = stage.GetPrimAtPath("/World")
    world.CreateAttribute("dftl:wind", Sdf.ValueTypeNames.Float3, custom=True).Set(Gf.Vec3f(30.0, 0.0, 0.0))
    if hair_hair:
        world.CreateAttribute("dftl:hairHair", Sdf.ValueTypeNames.Bool, custom=True).Set(True)
    animated_xform(stage, "/World/Head", translate={1: (5000, 100, -3000), 10: (5006, 100, -3000)},
                   rotate_y={1: 0.0, 10: 30.0})
    ball = UsdGeom.Sphere.Define(stage, "/World/Head/Ball")
    ball.CreateRadiusAttr(2.0)
    UsdGeom.XformCommonAPI(ball).SetTranslate(Gf.Vec3d(3.0, -6.0, 0.5))
    UsdPhysics.CollisionAPI.Apply(ball.GetPrim())
    rng = np.random.default_rng(3)
    for name, strands, vertices, drag in (("Long", 30, 11, 2.0), ("Short", 21, 5, 0.5)):
        pts = [chain(vertices, 0.8, direction=(rng.uniform(-1, 1), -1.0, 0.2), origin=(k * 0.3, 0, 0))
               for k in range(strands)]
        curves = add_curves(stage, f"/World/Head/{name}", np.concatenate(pts), [vertices] * strands, widths=0.05)
        prim = curves.GetPrim()
        prim.CreateAttribute("dftl:drag", Sdf.ValueTypeNames.Float, custom=True).Set(drag)
    stage.GetRootLayer().Save()
    return path


def test_split_with_colliders_wind_and_drag_equals_single_device(tmp_path):
    path = _featured_stage(tmp_path / "featured.usda")
    split, got = _frames(path, "cpu,cpu", frames=9)
    single, want = _frames(path, "cpu", frames=9)
    flags = single.groups[0].model.feature_flags
    assert {"spheres", "drag", "wind"} <= set(flags), flags
    assert split.groups[0].model.feature_flags == flags and len(split.groups[0].model.parts) == 2
    for frame_got, frame_want in zip(got, want):
        for (p, v), (q, w) in zip(frame_got, frame_want):
            assert p.tobytes() == q.tobytes() and v.tobytes() == w.tobytes()


def _strand_length(path):
    """Longest strand of the scene (stage units), the scale of its motion."""
    scene = read_scene(str(path))
    return max(float(np.max(np.add.reduceat(
        np.r_[0.0, np.linalg.norm(np.diff(c.points, axis=0), axis=1)] * np.isin(
            np.arange(c.num_points), np.cumsum(c.counts)[:-1], invert=True), np.r_[0, np.cumsum(c.counts)[:-1]])))
        for c in scene.curves)


# float32: this scene (contacts, grid) is chaotic in float32, where scaling a single-device run's
# velocities by 1 + 1e-6 after frame 1 moves frame 3 by 0.08 stage units, and the float32 run
# parts from the float64 one by 0.3 within 2 frames. The split run may part from the single-device
# one the same way, but it stays as close to the float64 run as the single-device run is (within
# 1.5 times), and so within twice that distance of the single-device run (measured 1.7 times, with
# the hair-hair grid's weights of 2026-11-27: 1.6e-5 against 9.5e-6 stage units on strands of 11). float64 stays within 1e-10 of the strand length for 9 frames.
@pytest.mark.parametrize("precision, frames", [("float32", 2), ("float64", 9)])
def test_split_with_hair_hair_equals_single_device(tmp_path, precision, frames):
    """The parts exchange the grid every substep: the result is the single-device one up to the
    order of the splat's sums, and the hair-hair effect is there."""
    path = _featured_stage(tmp_path / "hairhair.usda", hair_hair=True)
    split, got = _frames(path, "cpu,cpu", frames=frames, precision=precision)
    single, want = _frames(path, "cpu", frames=frames, precision=precision)
    _, without = _frames(_featured_stage(tmp_path / "plain.usda"), "cpu", frames=frames, precision=precision)
    assert "hair_hair" in single.groups[0].model.feature_flags and len(split.groups[0].model.parts) == 2
    assert split.groups[0].solver.exchange is not None
    scale = _strand_length(path)

    def distance(a, b, item):
        return max(float(np.max(np.abs(p[item] - q[item]))) for fa, fb in zip(a, b) for p, q in zip(fa, fb))

    worst, worst_v = distance(got, want, 0), distance(got, want, 1)
    effect = distance(want, without, 0)
    assert effect > 1e-3 * scale, (effect, scale)
    if precision == "float64":
        assert worst < 1e-10 * scale, (worst, scale)
        assert worst_v < 1e-7 * scale
    else:
        _, exact = _frames(path, "cpu", frames=frames, precision="float64")
        round_off = distance(want, exact, 0)
        # the split run is as close to the float64 run as the single-device one (round-off, amplified
        # by the chaos alike), so the two are within the sum of their distances to it
        assert distance(got, exact, 0) <= 1.5 * round_off
        assert worst <= 2.0 * round_off, (worst, round_off)


def test_split_hair_hair_grid_equals_single_device_grid(tmp_path):
    """After a substep's bounds and splat phases, every part holds the single-device grid (float64:
    the sums differ only in order)."""
    from dftl_warp.simulation.simulate import Simulation, SimulationOptions

    path = _featured_stage(tmp_path / "hairhair.usda", hair_hair=True)
    scene = read_scene(str(path))
    opts = dict(precision="float64", substeps=2)
    split = Simulation(scene, SimulationOptions(device="cpu,cpu,cpu", **opts), 1)
    single = Simulation(scene, SimulationOptions(device="cpu", **opts), 1)
    single.advance()  # move the hair off its rest shape so that velocities splat too
    single.advance()
    group, one = split.groups[0], single.groups[0]
    assert np.array_equal(group.model.origin, one.model.origin)  # device coordinates copied as they are
    positions = one.model.points_from_device(one.state.positions, relative=False)
    velocities = one.model.points_from_device(one.state.velocities, relative=False)
    for model, s, (p0, p1) in zip(group.model.parts, group.state.parts, group.point_ranges):
        s.write("positions", model.points_to_device(positions[p0:p1], relative=False))
        s.write("velocities", model.points_to_device(velocities[p0:p1], relative=False))
    solver = group.solver
    steps = [s._features for s in solver.parts]
    assert len(steps) == 3 and {tuple(s.model.feature_data.grid_shape) for s in steps} == {
        tuple(one.model.feature_data.grid_shape)}
    for step, s, c in zip(steps, group.state.parts, group.control.parts):
        step.pose_and_bounds(s, c, 0.5)
    solver.exchange.combine_bounds()
    for step, s in zip(steps, group.state.parts):
        step.splat(s)
    solver.exchange.combine_splats()
    ref = one.solver._features
    ref.pose_and_bounds(one.state, one.control, 0.5)
    ref.splat(one.state)
    want = {name: a.numpy() for name, a in ref.grid.items()}
    assert want["density"].sum() > 0 and np.abs(want["momentum"]).max() > 0
    for step in steps:
        got = {name: a.numpy() for name, a in step.grid.items()}
        assert got["lower"].tobytes() == want["lower"].tobytes()
        # sums of the same splats in another order: within a few units in the last place of the sum
        # (the hair that starts inside the ball is pushed out first, which changes the values)
        np.testing.assert_allclose(got["density"], want["density"], rtol=1e-14, atol=1e-12)
        np.testing.assert_allclose(got["momentum"], want["momentum"], rtol=1e-14, atol=1e-12)
        # each part alone splats only its own strands
        assert step.model.num_points < one.model.num_points


def test_split_with_a_splat_interval_equals_single_device(tmp_path, capsys):
    """dftl:hairHairSplatInterval 3 on two devices: the parts exchange the whole grid at each rebuild
    and the density alone in between, as one device rebuilds it, so the motion is the single-device
    one up to the order of the splat's sums (float64), and unlike every-substep rebuilds'. Before,
    a split groom rebuilt every substep and warned that the interval applies on one device only."""
    path = _featured_stage(tmp_path / "hairhair.usda", hair_hair=True)
    stage = Usd.Stage.Open(str(path))
    stage.GetPrimAtPath("/World").CreateAttribute("dftl:hairHairSplatInterval", Sdf.ValueTypeNames.Int,
                                                  custom=True).Set(3)
    stage.Save()
    frames = 6
    split, got = _frames(path, "cpu,cpu", frames=frames, precision="float64", substeps=7)
    single, want = _frames(path, "cpu", frames=frames, precision="float64", substeps=7)
    _, every = _frames(_featured_stage(tmp_path / "every.usda", hair_hair=True), "cpu", frames=frames,
                       precision="float64", substeps=7)
    assert split.groups[0].solver.exchange.mass == "mass" and len(split.groups[0].model.parts) == 2
    scale = _strand_length(path)

    def distance(a, b):
        return max(float(np.max(np.abs(p[0] - q[0]))) for fa, fb in zip(a, b) for p, q in zip(fa, fb))

    assert distance(got, want) < 1e-10 * scale, (distance(got, want), scale)
    assert distance(want, every) > 1e-6 * scale      # the interval changes the motion
    out = tmp_path / "out.usdc"
    assert main(["simulate", str(path), "-o", str(out), "--device", "cpu,cpu", "--end", "2"]) == 0
    assert "dftl:hairHairSplatInterval" not in capsys.readouterr().err
    assert out.exists()
