"""Simulation through USD: units, up axis, animated transforms, local space, settings, cubic
curves, zero-length segments, and the command's output."""

import numpy as np
import pytest
from pxr import Gf, Usd, UsdGeom
from usd_stages import add_curves, animated_xform, chain, composed_samples, local_to_world, new_stage, set_attr

from dftl_warp import cli, simulate_strands
from dftl_warp.usd.scene import transform_points
from dftl_warp.simulation.simulate import DEFAULT_SUBSTEPS, simulate_usd


def tip_after_one_frame(tmp_path, name, up, meters_per_unit, length):
    """A horizontal 11-particle chain of ``length`` units; its tip after one frame (position,
    velocity) in stage units."""
    stage = new_stage(tmp_path / f"{name}.usda", up=up, meters_per_unit=meters_per_unit, start=1, end=2)
    add_curves(stage, "/World/Hair", chain(11, length / 10), [11])
    stage.Save()
    out = tmp_path / f"{name}.usdc"
    simulate_usd(tmp_path / f"{name}.usda", out)
    return composed_samples(out, "/World/Hair")[2.0][-1], composed_samples(out, "/World/Hair", "velocities")[2.0][-1]


def test_centimetre_z_up_scene_falls_like_the_metre_y_up_scene(tmp_path):
    """Same physics in any units: 1 m of hair in cm/Z-up and in m/Y-up falls the same way, with
    the tip dropping about as far as free fall (981 cm/s^2) in the first frame."""
    p_cm, v_cm = tip_after_one_frame(tmp_path, "cm", "Z", 0.01, 100.0)
    p_m, v_m = tip_after_one_frame(tmp_path, "m", "Y", 1.0, 1.0)
    t = 1.0 / 24.0
    assert p_cm[1] == pytest.approx(0.0, abs=1e-6) and p_m[2] == pytest.approx(0.0, abs=1e-6)
    assert -1.25 < p_cm[2] / (0.5 * 981.0 * t * t) < -0.9  # falls along -Z, in cm
    assert -1.5 < v_cm[2] / (981.0 * t) < -0.9  # velocities in cm/s
    np.testing.assert_allclose([p_cm[0], p_cm[2]], [100 * p_m[0], 100 * p_m[1]], rtol=1e-4)
    np.testing.assert_allclose([v_cm[0], v_cm[2]], [100 * v_m[0], 100 * v_m[1]], atol=1e-4 * abs(v_cm[2]))


def test_animated_parent_transform_carries_roots_and_results_are_local(tmp_path):
    """Roots follow the animated (translating + turning) parent on the C1 root path across
    substeps (cubic Hermite between the frames' roots, tangents their fourth-order differences
    over the shot's frames, one-sided at its ends: docs/usd.md); the result equals a world-space
    reference simulation and is written in local space."""
    frames, substeps, fps = 8, 4, 24.0
    stage = new_stage(tmp_path / "in.usda", start=1, end=frames)
    animated_xform(stage, "/World/Head", translate={1: (0, 0, 0), 4: (0.3, 0.1, 0), 8: (0.2, -0.2, 0.4)},
                   rotate_y={1: 0.0, 8: 120.0})
    static = UsdGeom.Xform.Define(stage, "/World/Head/Offset")
    static.AddTranslateOp().Set(Gf.Vec3d(0.0, 0.5, 0.0))
    static.AddRotateXOp().Set(30.0)
    static.AddScaleOp().Set(Gf.Vec3f(0.5, 0.5, 0.5))
    local = np.concatenate([chain(6, 0.1), chain(4, 0.1, direction=(0, 0, 1), origin=(0.2, 0, 0))])
    add_curves(stage, "/World/Head/Offset/Hair", local, [6, 4])
    stage.Save()
    out = tmp_path / "out.usdc"
    simulate_usd(tmp_path / "in.usda", out, substeps=substeps)

    # reference: world-space simulation with the root targets of every substep on the C1 path
    starts = np.array([0, 6])
    m = {f: local_to_world(tmp_path / "in.usda", "/World/Head/Offset/Hair", f) for f in range(1, frames + 1)}
    at = {f: transform_points(m[f], local[starts]) for f in m}
    # fourth-order differences over 5 frames, the window kept inside the shot (frames 1..8)
    stencils = {0: [-25, 48, -36, 16, -3], 1: [-3, -10, 18, -6, 1], 2: [1, -8, 0, 8, -1],
                3: [-1, 6, -18, 10, 3], 4: [3, -16, 36, -48, 25]}
    T = 1.0 / fps

    def velocity(f):
        lo = min(max(f - 2, 1), frames - 4)
        return sum(w * at[lo + j] for j, w in enumerate(stencils[f - lo])) / (12.0 * T)

    roots = [at[1]]
    for f in range(1, frames):
        for k in range(1, substeps + 1):
            u = k / substeps   # Hermite basis: h00 x0 + h10 T v0 + h01 x1 + h11 T v1
            roots.append((2 * u**3 - 3 * u**2 + 1) * at[f] + (u**3 - 2 * u**2 + u) * T * velocity(f)
                         + (3 * u**2 - 2 * u**3) * at[f + 1] + (u**3 - u**2) * T * velocity(f + 1))
    ref = simulate_strands(transform_points(m[1], local), [6, 4], steps=(frames - 1) * substeps,
                           dt=1.0 / (fps * substeps), gravity=(0.0, -9.81, 0.0), record_every=substeps,
                           roots=np.array(roots))

    points = composed_samples(out, "/World/Head/Offset/Hair")
    velocities = composed_samples(out, "/World/Head/Offset/Hair", "velocities")
    assert sorted(points) == [float(f) for f in range(1, frames + 1)]
    for f in range(1, frames + 1):
        p = points[float(f)]
        np.testing.assert_allclose(p[starts], local[starts], atol=2e-5)  # roots pinned in local space
        np.testing.assert_allclose(transform_points(m[f], p), ref.positions[f - 1], atol=2e-5)
        np.testing.assert_allclose(velocities[float(f)][starts], 0.0, atol=2e-3)  # roots do not move locally
    moved = np.linalg.norm(transform_points(m[frames], points[float(frames)]) - transform_points(m[1], local), axis=1)
    assert moved.min() > 0.1  # the whole groom travelled with the head


def test_local_velocities_are_the_rate_of_change_of_local_points(tmp_path):
    """Under a moving, turning parent the written velocities are d/dt of the written (local)
    points -- what renderers expect, adding the transform's motion blur themselves. The parent
    moves at 1 m/s, far more than the tolerance, so ignoring its motion would fail."""
    fps, frames = 24.0, 24
    stage = new_stage(tmp_path / "in.usda", start=1, end=frames)
    animated_xform(stage, "/World/Head", translate={1: (0, 0, 0), frames: (23 / fps, 0, 0)},
                   rotate_y={1: 0.0, frames: 30.0})
    add_curves(stage, "/World/Head/Hair", chain(6, 0.1), [6])
    stage.Save()
    simulate_usd(tmp_path / "in.usda", tmp_path / "o.usdc", substeps=16)
    points = composed_samples(tmp_path / "o.usdc", "/World/Head/Hair")
    velocities = composed_samples(tmp_path / "o.usdc", "/World/Head/Hair", "velocities")
    for f in (5.0, 12.0, 20.0):
        rate = (points[f + 1] - points[f - 1]) * fps / 2  # central difference
        speed = np.abs(velocities[f]).max()
        assert speed > 0.5
        assert np.abs(velocities[f] - rate).max() < 0.08 * speed
        assert 0.08 * speed < 0.5  # well below the parent's own speed (1 m/s)


def test_static_transform_velocities_use_the_linear_part(tmp_path):
    stage = new_stage(tmp_path / "in.usda", start=1, end=3)
    xf = UsdGeom.Xform.Define(stage, "/World/Turned")
    xf.AddTranslateOp().Set(Gf.Vec3d(5.0, 0.0, 0.0))
    xf.AddRotateXOp().Set(90.0)
    add_curves(stage, "/World/Turned/Hair", chain(5, 0.1), [5])
    stage.Save()
    out = tmp_path / "out.usdc"
    simulate_usd(tmp_path / "in.usda", out)
    m = local_to_world(tmp_path / "in.usda", "/World/Turned/Hair", 1)
    ref = simulate_strands(transform_points(m, chain(5, 0.1)), [5], steps=2 * DEFAULT_SUBSTEPS,
                           dt=1 / (24.0 * DEFAULT_SUBSTEPS), gravity=(0, -9.81, 0), record_every=DEFAULT_SUBSTEPS)
    v = composed_samples(out, "/World/Turned/Hair", "velocities")[3.0]
    np.testing.assert_allclose(v @ m[:3, :3], ref.velocities[2], atol=1e-5)
    assert np.abs(v[:, 2]).max() > 0.1  # world -Y is local +Z after the 90 degree turn about X


def test_zero_length_segments_simulate_without_nan(tmp_path):
    """Policy: coincident consecutive points are simulated (a rigid zero-length link), not refused."""
    pts = np.array([[0, 0, 0], [0.1, 0, 0], [0.1, 0, 0], [0.2, 0, 0], [0.2, 0, 0], [0.2, 0, 0]], dtype=float)
    stage = new_stage(tmp_path / "in.usda", start=1, end=24)
    add_curves(stage, "/World/Hair", np.concatenate([pts, np.zeros((2, 3))]), [6, 2])
    stage.Save()
    simulate_usd(tmp_path / "in.usda", tmp_path / "o.usdc")
    points = composed_samples(tmp_path / "o.usdc", "/World/Hair")
    velocities = composed_samples(tmp_path / "o.usdc", "/World/Hair", "velocities")
    for t, p in points.items():
        assert np.isfinite(p).all() and np.isfinite(velocities[t]).all()
        lengths = np.linalg.norm(np.diff(p[:6], axis=0), axis=1)
        np.testing.assert_allclose(lengths, [0.1, 0.0, 0.1, 0.0, 0.0], atol=1e-5)
        np.testing.assert_allclose(p[6:], 0.0, atol=1e-6)  # a strand of two coincident points
    assert points[24.0][5, 1] < -0.05  # and it did move


def test_cubic_curves_simulate_control_points_and_keep_their_kind(tmp_path):
    stage = new_stage(tmp_path / "in.usda", start=1, end=4)
    add_curves(stage, "/World/Bez", chain(7, 0.05), [7], curve_type="cubic", basis="bezier")
    add_curves(stage, "/World/Bsp", chain(5, 0.05), [5], curve_type="cubic", basis="bspline", wrap="pinned")
    stage.Save()
    simulate_usd(tmp_path / "in.usda", tmp_path / "o.usdc")
    out = Usd.Stage.Open(str(tmp_path / "o.usdc"))
    for path, basis, wrap, n in (("/World/Bez", "bezier", "nonperiodic", 7), ("/World/Bsp", "bspline", "pinned", 5)):
        c = UsdGeom.BasisCurves(out.GetPrimAtPath(path))
        assert (c.GetTypeAttr().Get(), c.GetBasisAttr().Get(), c.GetWrapAttr().Get()) == ("cubic", basis, wrap)
        p = np.array(c.GetPointsAttr().Get(4.0))
        assert p.shape == (n, 3) and p[-1, 1] < -0.01
        np.testing.assert_allclose(np.linalg.norm(np.diff(p, axis=0), axis=1), 0.05, rtol=1e-4)


def test_dftl_settings_group_prims_and_flags_override_them(tmp_path):
    stage = new_stage(tmp_path / "in.usda", start=1, end=5)
    a = add_curves(stage, "/World/A", chain(6, 0.1), [6]).GetPrim()
    add_curves(stage, "/World/B", chain(6, 0.1, origin=(0, 0, 1)), [6])
    set_attr(a, "dftl:damping", "Float", 0.0)
    set_attr(a, "dftl:substeps", "Int", 2)
    set_attr(a, "dftl:correction", "Token", "posterior")
    stage.Save()
    summary = simulate_usd(tmp_path / "in.usda", tmp_path / "o.usdc")
    groups = sorted((g["damping"], g["substeps"], g["correction"], g["prims"]) for g in summary.groups)
    assert groups == [(0.0, 2, "posterior", 1), (1.0, DEFAULT_SUBSTEPS, "prior", 1)]
    # prim A was simulated with its own settings
    ref = simulate_strands(chain(6, 0.1), [6], steps=8, dt=1 / 48.0, damping=0.0, correction="posterior",
                           gravity=(0, -9.81, 0), record_every=2)
    got = composed_samples(tmp_path / "o.usdc", "/World/A")
    np.testing.assert_allclose(got[5.0], ref.positions[4], atol=1e-5)

    summary = simulate_usd(tmp_path / "in.usda", tmp_path / "o2.usdc", damping=0.5, substeps=3, correction="prior")
    assert [(g["damping"], g["substeps"], g["correction"], g["prims"]) for g in summary.groups] == [(0.5, 3, "prior", 2)]


def test_prim_flag_writes_only_the_selected_prims(tmp_path, capsys):
    stage = new_stage(tmp_path / "in.usda", start=1, end=3)
    add_curves(stage, "/World/A", chain(3, 0.1), [3])
    add_curves(stage, "/World/B", chain(3, 0.1), [3])
    stage.Save()
    code = cli.main(["simulate", str(tmp_path / "in.usda"), "-o", str(tmp_path / "o.usdc"), "--prim", "/World/B",
                     "--quiet"])
    assert code == 0
    out = Usd.Stage.Open(str(tmp_path / "o.usdc"))
    assert out.GetPrimAtPath("/World/A").GetAttribute("points").GetNumTimeSamples() == 0
    assert out.GetPrimAtPath("/World/B").GetAttribute("points").GetNumTimeSamples() == 3


def test_command_shows_progress_on_stderr_and_a_summary(tmp_path, capsys):
    stage = new_stage(tmp_path / "in.usda", start=1, end=6)
    add_curves(stage, "/World/Hair", np.concatenate([chain(4, 0.1), chain(4, 0.1, origin=(0, 0, 1))]), [4, 4])
    stage.Save()
    argv = ["simulate", str(tmp_path / "in.usda"), "-o", str(tmp_path / "o.usdc"), "--substeps", "2",
            "--precision", "float64", "--solver", "ftl"]
    assert cli.main(argv) == 0
    out, err = capsys.readouterr()
    assert "6/6" in err and "frame" in err  # the tqdm bar
    line = out.strip()
    assert line.count("\n") == 0
    for piece in ("2 strands", "8 particles", "6 frames (1..6)", "loading", "simulating", "writing"):
        assert piece in line
    assert cli.main(argv + ["--quiet"]) == 0
    out, err = capsys.readouterr()
    assert err == "" and "2 strands" in out


def test_solver_choices_come_from_the_solver_registry(monkeypatch):
    from dftl_warp.solvers import SOLVERS, DFTLSolver

    monkeypatch.setitem(SOLVERS, "future", DFTLSolver)
    parser = cli.build_parser()
    sub = next(a for a in parser._actions if a.dest == "command")
    choices = next(a for a in sub.choices["simulate"]._actions if a.dest == "solver").choices
    assert tuple(choices) == tuple(SOLVERS) and "future" in choices


def test_info_command_describes_the_default_scene(capsys):
    from pathlib import Path

    scene = Path(__file__).resolve().parent.parent / "scenes" / "default.usda"
    assert cli.main(["info", str(scene)]) == 0
    out = capsys.readouterr().out
    for piece in ("0.01 m per unit, up axis Y", "1..72 at 24 per second", "(0, -981, 0) units/s^2",
                  "3000 strands, 48000 particles", "per strand in float32", "/World/Head/Hair",
                  "animated transform", "/World/Head/Skull: sphere, friction 0.3"):
        assert piece in out, piece
    assert cli.main(["info", str(scene), "--json"]) == 0
    import json

    d = json.loads(capsys.readouterr().out)
    assert d["strands"] == 3000 and d["device_bytes_per_strand"]["float64"] > d["device_bytes_per_strand"]["float32"]


def test_samples_of_earlier_frames_stay_valid(tmp_path):
    """samples() returns arrays the caller owns: the next frame does not overwrite them."""
    from dftl_warp.simulation.simulate import Simulation, SimulationOptions
    from dftl_warp.usd.read import read_scene

    stage = new_stage(tmp_path / "s.usda", start=1, end=3)
    add_curves(stage, "/World/Hair", chain(5, spacing=0.1), [5])
    stage.GetRootLayer().Save()
    sim = Simulation(read_scene(str(tmp_path / "s.usda")), SimulationOptions(start=1, end=3), 1)
    first = sim.samples()[0][0]
    kept = first.copy()
    sim.advance()
    second = sim.samples()[0][0]
    assert np.array_equal(first, kept) and not np.array_equal(first, second)
