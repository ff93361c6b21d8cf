"""The energy-growth warning (dftl_warp.simulation.monitor) counts the work of moving colliders.

Before, a strand's budget counted only its root's motion: hair hanging at rest, struck by a sphere,
a moved mesh or a deforming mesh passing through it at 1-3 m/s, was called unstable ('energy grew to
2.47 J/kg at frame 12, more than 0.00883 J/kg ... this setting is unstable') on a stable run. Now a
moving collider within a strand's reach counts as its root's motion does; static colliders and
colliders out of reach change no budget, so unstable settings still warn.
"""

from __future__ import annotations

import numpy as np
import pytest
from pxr import Gf, UsdGeom, UsdPhysics, Vt
from test_energy_warning_resume import simulate_frames
from test_features import box_mesh
from test_usd_features import sphere_collider
from usd_stages import add_curves, chain, new_stage

from dftl_warp import cli

FPS = 24.0


def grown_lines(err: str) -> list[str]:
    return [line for line in err.splitlines() if "energy grew" in line]


def hanging_hair(stage):
    """9 strands of 30 cm hanging straight down (at rest) from roots 2 cm apart around the origin."""
    pts = np.concatenate([chain(16, 0.02, direction=(0.0, -1.0, 0.0), origin=(x, 0.0, z))
                          for x in (-0.02, 0.0, 0.02) for z in (-0.02, 0.0, 0.02)])
    add_curves(stage, "/World/Hair", pts, [16] * 9, widths=1e-4, bending=True)


def add_collider(stage, kind, center, half=(0.04, 0.04, 0.04)):
    """A collider of ``kind`` whose centre is ``center(frame)`` at every frame of the stage: a sphere
    (radius 5 cm) or a box mesh (half extents ``half``) under an animated Xform, or a box mesh whose
    points are time-sampled."""
    frames = range(int(stage.GetStartTimeCode()), int(stage.GetEndTimeCode()) + 1)
    points, faces = box_mesh(half)
    if kind == "deforming":
        mesh = UsdGeom.Mesh.Define(stage, "/World/Pusher")
        attr = mesh.CreatePointsAttr()
        for f in frames:
            attr.Set(Vt.Vec3fArray.FromNumpy((points + center(f)).astype(np.float32)), f)
    else:
        op = UsdGeom.Xform.Define(stage, "/World/Mover").AddTranslateOp()
        for f in frames:
            op.Set(Gf.Vec3d(*center(f)), f)
        if kind == "sphere":
            sphere_collider(stage, "/World/Mover/Pusher", 0.05)
            return
        mesh = UsdGeom.Mesh.Define(stage, "/World/Mover/Pusher")
        mesh.CreatePointsAttr(Vt.Vec3fArray.FromNumpy(points.astype(np.float32)))
    mesh.CreateFaceVertexCountsAttr(Vt.IntArray([3] * len(faces)))
    mesh.CreateFaceVertexIndicesAttr(Vt.IntArray([int(i) for i in faces.reshape(-1)]))
    UsdPhysics.CollisionAPI.Apply(mesh.GetPrim())


def through_the_hair(speed, end=24):
    """A centre that crosses the hair 20 cm below the roots at ``speed`` m/s, midway in the shot."""
    x0 = -0.5 * speed * (end - 1) / FPS
    return lambda f: np.array([x0 + speed * (f - 1) / FPS, -0.2, 0.0])


def from_the_side(speed):
    """A centre that comes at the hair from 5 cm beside the first strands at ``speed`` m/s."""
    return lambda f: np.array([-0.07 + speed * (f - 1) / FPS, -0.2, 0.0])


def lifting(speed):
    """A centre that rises under the hair at ``speed`` m/s, from 35 cm below the roots."""
    return lambda f: np.array([0.01, -0.35 + speed * (f - 1) / FPS, 0.005])


@pytest.mark.parametrize("kind, path, solver", [
    ("sphere", through_the_hair(1.0), None), ("sphere", through_the_hair(3.0), "dftl"),
    ("mesh", through_the_hair(2.0), None), ("deforming", from_the_side(0.025), "dftl"),
    ("plate", lifting(0.3), None)])
def test_hair_struck_by_a_moving_collider_is_not_called_unstable(tmp_path, capsys, kind, path, solver):
    """Spheres and a moved mesh through hanging hair, a deforming mesh that pushes it aside (slowly,
    as written when its points jumped once a frame and hair let one through that jumped farther than
    its depth band; they move inside the frame since ba19086),
    and a plate that carries it up slowly: a collider at 0.3 m/s can only throw hair at 0.6 m/s
    (0.18 J/kg a particle), but it lifts it by up to 35 cm (3.4 J/kg a particle), work all the same."""
    stage = new_stage(tmp_path / "in.usda", start=1, end=24)
    hanging_hair(stage)
    if kind == "plate":
        add_collider(stage, "mesh", path, half=(0.15, 0.02, 0.15))
    else:
        add_collider(stage, kind, path)
    stage.Save()
    args = ["simulate", str(tmp_path / "in.usda"), "-o", str(tmp_path / "out.usdc")]
    assert cli.main(args + (["--solver", solver] if solver else [])) == 0
    err = capsys.readouterr().err
    assert not grown_lines(err), err


def _per_strand(monitor, name) -> np.ndarray:
    """The monitor's per-strand record ``name`` in input strand order (the parts of a split one joined)."""
    out = []
    for m in getattr(monitor, "parts", [monitor]):
        values = getattr(m, name)
        out.append(np.empty_like(values))
        out[-1][m.model.layout.strand_order] = values
    return np.concatenate(out)


@pytest.mark.parametrize("device", ["cpu", "cpu,cpu"])
def test_each_strand_counts_the_colliders_that_reach_it_at_their_speed(tmp_path, device):
    """A sphere animated at 2 m/s (0.8 m in 0.4 s) passes through one tuft and stays 0.7 m clear of
    another: the first tuft's strands count a collider of 2 m/s, the second's none, on one device
    and split over two."""
    stage = new_stage(tmp_path / "in.usda", start=1, end=12)
    near = [chain(16, 0.02, direction=(0.0, -1.0, 0.0), origin=(0.0, 0.0, z)) for z in (-0.02, 0.02)]
    far = [chain(16, 0.02, direction=(0.0, -1.0, 0.0), origin=(0.0, 0.0, 1.0 + z)) for z in (-0.02, 0.02)]
    add_curves(stage, "/World/Hair", np.concatenate(near + far), [16] * 4, widths=0.002, bending=True)
    add_collider(stage, "sphere", lambda f: np.array([-0.4 + 2.0 * (f - 1) / FPS, -0.2, 0.0]))
    stage.Save()
    sim, warned = simulate_frames(tmp_path / "in.usda", device, 10)
    assert not warned, warned
    speeds = _per_strand(sim.groups[0].monitor, "collider_speed")
    assert speeds[:2] == pytest.approx(2.0, rel=0.02), speeds
    assert np.all(speeds[2:] == 0.0), speeds


def _unstable_stage(path, colliders):
    # DFTL with s = 0 at 40 substeps a frame pumps energy into a horizontal chain (test_stability)
    stage = new_stage(path, start=1, end=24)
    add_curves(stage, "/World/Hair", chain(64, 0.005, direction=(1.0, 0.0, 0.0)), [64])
    if colliders:
        sphere_collider(stage, "/World/Still", 0.1, translate=(0.1, -1.0, 0.0))       # 1 m below the hair
        add_collider(stage, "sphere", lambda f: np.array([3.0 + 0.1 * f / FPS, 0.0, 0.0]))   # 0.1 m/s, 3 m away
    stage.Save()
    return str(path)


def test_unstable_setting_still_warns_beside_static_and_distant_colliders(tmp_path, capsys):
    found = {}
    for colliders in (False, True):
        path = _unstable_stage(tmp_path / f"in{colliders}.usda", colliders)
        assert cli.main(["simulate", path, "-o", str(tmp_path / f"{colliders}.usdc"), "--solver", "dftl",
                         "--damping", "0", "--substeps", "40"]) == 0
        lines = grown_lines(capsys.readouterr().err)
        assert len(lines) == 1 and "use s = 1" in lines[0], lines
        found[colliders] = lines[0].split(": energy grew to ")[1].split(" (")[0]
    assert found[True] == found[False], found   # the same energy, frame and budget


def _fast_then_slow(kind):
    """Through the hair at 3 m/s for 8 frames, then on at 0.05 m/s among the strands."""
    def center(f):
        x = -0.6 + 3.0 * (min(f, 9) - 1) / FPS + 0.05 * max(f - 9, 0) / FPS
        return np.array([x, -0.2, 0.0])
    return center


@pytest.mark.parametrize("kind", ["sphere", "deforming"])
def test_resumed_run_keeps_the_colliders_it_counted(tmp_path, kind):
    """A run resumed after a collider struck the hair fast keeps counting that speed (the hair still
    moves from it): it warns as the uninterrupted run does (not at all), with the same records."""
    stage = new_stage(tmp_path / "in.usda", start=1, end=16)
    hanging_hair(stage)
    add_collider(stage, kind, _fast_then_slow(kind))
    stage.Save()
    path = tmp_path / "in.usda"
    for device in ("cpu", "cpu,cpu"):
        whole, want = simulate_frames(path, device, 16, solver="dftl")
        assert not want, want
        first, before = simulate_frames(path, device, 10, solver="dftl")
        resumed, after = simulate_frames(path, device, 16, first.save_state(), solver="dftl")
        assert before + after == want, (before, after)
        for name in ("collider_speed", "worst_ratio"):
            np.testing.assert_array_equal(*(_per_strand(s.groups[0].monitor, name) for s in (whole, resumed)))


def test_a_state_saved_before_the_check_counted_colliders_restarts_the_check(tmp_path):
    """A checkpoint whose energy records lack the colliders' (one saved before the check counted
    them) restarts the check from the resumed frame, as a state without energy records does."""
    stage = new_stage(tmp_path / "in.usda", start=1, end=16)
    hanging_hair(stage)
    add_collider(stage, "sphere", through_the_hair(2.0, end=16))
    stage.Save()
    first, _ = simulate_frames(tmp_path / "in.usda", "cpu", 10, solver="dftl")
    saved = {k: v for k, v in first.save_state().items() if k != "group0.monitor.record6"}
    assert np.any(_per_strand(first.groups[0].monitor, "collider_speed") > 0)
    resumed, warned = simulate_frames(tmp_path / "in.usda", "cpu", 10, saved, solver="dftl")
    assert not warned, warned
    monitor = resumed.groups[0].monitor   # restarted: the loaded state is its start, no collider seen yet
    assert np.all(monitor.collider_speed == 0.0) and np.all(monitor.worst_ratio <= 0.5), monitor.worst_ratio
