"""The roots' C1 path inside a frame (dftl_warp.kernels.core.root_path, Control's velocities).

1. The helper: zero tangent deviations reproduce the linear path bit for bit, tangents equal to
   the chord reproduce it to round-off, and a cubic has the given positions and velocities at
   the frame's ends (the Hermite interpolant of the same data, fitted independently).
2. Through ``simulate_usd``: an elastic strand of 80 um hair, L = l_b, started at its equilibrium,
   whose parent Xform shakes the root 1 cm at 1 Hz; the written velocities agree with the central
   difference of the written points (p1/p99 of the ratio in [0.8, 1.25], the definition of
   scripts/elastic_study.py).
3. Animated colliders ride the same path: a head (a sphere collider) turning and bobbing with the
   roots under one animated Xform keeps every root where the head holds it, at every substep.
"""

from __future__ import annotations

import numpy as np
import pytest
import warp as wp

import dftl_warp as dw
from dftl_warp.kernels.core.root_path import root_on_path

wp.config.quiet = True

FPS = 24.0


@wp.kernel(enable_backward=False, module="unique")
def _paths(start: wp.array(dtype=wp.vec3d), end: wp.array(dtype=wp.vec3d), d0: wp.array(dtype=wp.vec3d),
           d1: wp.array(dtype=wp.vec3d), alpha: wp.array(dtype=wp.float64),
           on_path: wp.array(dtype=wp.vec3d), linear: wp.array(dtype=wp.vec3d)):
    i = wp.tid()
    on_path[i] = root_on_path(start[i], end[i] - start[i], d0[i], d1[i], alpha[i])
    linear[i] = start[i] + alpha[i] * (end[i] - start[i])   # the Control's path before the C1 one


def paths(start, end, d0, d1, alpha):
    n = len(alpha)
    arr = lambda a: wp.array(np.broadcast_to(np.asarray(a, float), (n, 3)).copy(), dtype=wp.vec3d,  # noqa: E731
                             device="cpu")
    out = [wp.zeros(n, dtype=wp.vec3d, device="cpu") for _ in range(2)]
    wp.launch(_paths, dim=n, device="cpu", inputs=[arr(start), arr(end), arr(d0), arr(d1),
                                                   wp.array(np.asarray(alpha, float), dtype=wp.float64, device="cpu")],
              outputs=out)
    return out[0].numpy(), out[1].numpy()


def test_zero_deviations_are_the_linear_path_bit_for_bit():
    rng = np.random.default_rng(3)
    alpha = np.concatenate([[0.0, 1.0], np.arange(1, 8) / 8.0, rng.random(50)])
    start, end = rng.normal(size=3) * 0.3, rng.normal(size=3) * 0.3
    on_path, linear = paths(start, end, 0.0, 0.0, alpha)
    assert np.array_equal(on_path, linear)


def test_tangents_equal_to_the_chord_give_the_linear_path():
    """Hermite with T v0 = T v1 = end - start is the straight line (h10 + h11 + h01 = alpha):
    through the Control, which turns velocities into deviations on the host."""
    pts = np.array([[0.0, 0.0, 0.0, 0.01, 0.0, 0.0], [0.3, -0.1, 0.2, 0.3, -0.09, 0.2]]).reshape(-1, 3)
    model = dw.Model.from_strands(pts, [2, 2], precision="float64", device="cpu")
    control = model.control()
    start = pts[[0, 2]]
    end = start + np.array([[0.02, -0.01, 0.005], [-0.3, 0.1, 0.0]])
    T = 1.0 / FPS
    chord_velocity = (end - start) / T
    control.set_root_targets(start, end, velocity_start=chord_velocity, velocity_end=chord_velocity, frame_duration=T)
    dev = np.concatenate([control.root_deviation_start.numpy(), control.root_deviation_end.numpy()])
    assert np.abs(dev).max() <= 1e-15
    assert np.allclose(control.root_velocity_start, chord_velocity, rtol=1e-12, atol=0)
    alpha = np.linspace(0, 1, 17)
    for s in range(2):
        on_path, linear = paths(start[s], end[s], dev[s], dev[2 + s], alpha)
        assert np.abs(on_path - linear).max() <= 1e-15
    # and setting no velocities afterwards goes back to exactly zero deviations
    control.set_root_targets(end, start)
    assert control.frame_duration == 0.0 and not control.root_deviation_start.numpy().any()
    assert control.root_velocity_start is None


def test_a_cubic_path_has_its_end_positions_and_velocities():
    """Positions and velocities at the frame's ends are the given ones, and the path is the
    standard cubic Hermite interpolant h00 p0 + h10 T v0 + h01 p1 + h11 T v1."""
    T = 1.0 / FPS
    p0, p1 = np.array([0.1, -0.2, 0.05]), np.array([0.13, -0.18, 0.02])
    v0, v1 = np.array([0.9, -0.3, 0.2]), np.array([-0.4, 0.6, -0.1])
    chord = p1 - p0
    alpha = np.linspace(0.0, 1.0, 41)
    on_path, _ = paths(p0, p1, T * v0 - chord, T * v1 - chord, alpha)
    a = alpha[:, None]
    h00, h10, h01, h11 = 2 * a**3 - 3 * a**2 + 1, a**3 - 2 * a**2 + a, -2 * a**3 + 3 * a**2, a**3 - a**2
    hermite = h00 * p0 + h10 * T * v0 + h01 * p1 + h11 * T * v1
    assert np.abs(on_path - hermite).max() <= 1e-15
    assert np.array_equal(on_path[0], p0) and np.abs(on_path[-1] - p1).max() <= 1e-16
    # velocities at the ends from an exact cubic fit of the computed path (dx/dt = dx/dalpha / T)
    coeffs = [np.polynomial.polynomial.polyfit(alpha, on_path[:, c], 3) for c in range(3)]
    dx = np.array([[np.polynomial.polynomial.polyval(x, np.polynomial.polynomial.polyder(k)) for k in coeffs]
                   for x in (0.0, 1.0)]) / T
    assert np.allclose(dx[0], v0, rtol=0, atol=1e-10) and np.allclose(dx[1], v1, rtol=0, atol=1e-10)


def test_control_velocity_arguments_are_checked():
    model = dw.Model.from_strands(np.array([[0.0, 0.0, 0.0], [0.01, 0.0, 0.0]]), [2], device="cpu")
    control = model.control()
    roots = np.zeros((1, 3))
    with pytest.raises(ValueError, match="frame_duration"):
        control.set_root_targets(roots, roots, velocity_start=roots)
    with pytest.raises(ValueError, match="velocity_start"):
        control.set_root_targets(roots, roots, frame_duration=0.04)
    with pytest.raises(ValueError, match="finite"):
        control.set_root_targets(roots, roots, velocity_start=[[np.nan, 0, 0]], frame_duration=0.04)


# ---------------------------------------------------------------------------------------------
# 2. through simulate_usd: a shaken root

AMPLITUDE = 0.01   # m
FRAMES = 48


def shaken_strand_stage(path):
    """/World/Root (animated Xform: y = A (1 - cos 2 pi t) / 2, 1 Hz, at rest at frame 1) holding
    one horizontal strand of 80 um hair, L = l_b (widths: the elastic solver by default)."""
    from usd_stages import add_curves, animated_xform, chain, new_stage

    from dftl_warp.solvers.elastic import HAIR_DENSITY, HAIR_E

    r = 40e-6
    lb = (HAIR_E * np.pi * r**4 / 4 / (HAIR_DENSITY * np.pi * r**2 * 9.81)) ** (1.0 / 3.0)
    stage = new_stage(path, start=1, end=1 + FRAMES, fps=FPS)
    shake = {f: (0.0, AMPLITUDE * (1 - np.cos(2 * np.pi * (f - 1) / FPS)) / 2, 0.0) for f in range(1, FRAMES + 2)}
    animated_xform(stage, "/World/Root", translate=shake)
    add_curves(stage, "/World/Root/Hair", chain(33, lb / 32), [33], widths=2 * r, bending=None)
    stage.Save()
    return lb


def velocity_ratios(path, first_frame):
    """|written velocity| / |central difference of the written points|, both local (USD's
    velocities), over the non-root points of the inner frames from ``first_frame`` on where the
    central difference is at least 10 % of its largest: p1, median, p99 (the definition of
    scripts/elastic_study.py ``velocities`` and scripts/elastic_root_drive.py)."""
    from pxr import Usd, UsdGeom

    stage = Usd.Stage.Open(str(path))
    curves = UsdGeom.BasisCurves(stage.GetPrimAtPath("/World/Root/Hair"))
    frames = range(first_frame, FRAMES + 2)
    x = np.array([np.asarray(curves.GetPointsAttr().Get(f), dtype=np.float64) for f in frames])[:, 1:]
    v = np.array([np.asarray(curves.GetVelocitiesAttr().Get(f), dtype=np.float64) for f in frames])[:, 1:]
    cd = np.linalg.norm(x[2:] - x[:-2], axis=2).ravel() * FPS / 2
    speed = np.linalg.norm(v[1:-1], axis=2).ravel()
    moving = cd >= 0.1 * cd.max()
    return np.percentile(speed[moving] / cd[moving], [1, 50, 99])


def test_shaken_root_velocities_agree_with_the_written_points(tmp_path):
    """The strand L = l_b shaken 1 cm at 1 Hz (the case of scripts/elastic_root_drive.py), through
    simulate_usd with the defaults (elastic, 8 substeps, float32). Measured over the second
    second: the drive's sudden acceleration at t = 0 plucks the strand's 8 Hz bending, which 24 fps
    samples three times a period (a ratio of w dt / sin(w dt) = 2.4 whatever the velocities are)
    until the scheme's numerical damping has taken it out (about 0.7 s)."""
    src = tmp_path / "shake.usda"
    shaken_strand_stage(src)
    summary = dw.simulate_usd(str(src), str(tmp_path / "out.usdc"), device="cpu")
    assert summary.groups[0]["solver"] == "elastic" and summary.groups[0]["substeps"] == 8
    p1, _, p99 = velocity_ratios(tmp_path / "out.usdc", first_frame=25)
    # measured (2-core CPU VM, 2026-11-24): 0.96 / 1.06; with the roots linear across each frame
    # and the frame's velocity its last frame's mean (before the C1 path): 0.50 / 49.7
    assert 0.8 <= p1 and p99 <= 1.25, (p1, p99)


def test_bound_roots_follow_the_path_of_their_mesh():
    """Roots bound to a deforming mesh: their velocities are the barycentric sums of the mesh
    points' (an affine map keeps barycentric weights), and the strand's root moves on the same
    Hermite curve as a root given those targets and velocities directly."""
    from dftl_warp import features as F

    mesh = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    root = np.array([0.2, 0.0, 0.3])
    pts = root + np.arange(4)[:, None] * [0.0, -0.05, 0.0]
    model = dw.Model.from_strands(pts, [4], precision="float64", device="cpu",
                                  features=[F.RootBinding(mesh, [[0, 1, 2]])])
    control = model.control()
    T = 1.0 / FPS
    stretch = lambda s: mesh * [1.0 + s, 1.0, 1.0] + [0.0, 0.3 * s, 0.0]  # noqa: E731  (an affine map)
    v_mesh = lambda s_rate: mesh * [s_rate, 0.0, 0.0] + [0.0, 0.3 * s_rate, 0.0]  # noqa: E731
    control.bind_roots(stretch(0.1), stretch(0.2), velocity_start=v_mesh(2.0), velocity_end=v_mesh(-1.0),
                       frame_duration=T)
    start, end = root * [1.1, 1, 1] + [0, 0.03, 0], root * [1.2, 1, 1] + [0, 0.06, 0]
    v0, v1 = root * [2.0, 0, 0] + [0, 0.6, 0], root * [-1.0, 0, 0] + [0, -0.3, 0]
    assert np.allclose(control.root_velocity_start[0], v0, atol=1e-12)
    assert np.allclose(control.root_velocity_end[0], v1, atol=1e-12)
    direct = model.control()
    direct.set_root_targets(start[None], end[None], velocity_start=v0[None], velocity_end=v1[None], frame_duration=T)
    for name in ("root_start", "root_end", "root_deviation_start", "root_deviation_end"):
        assert np.allclose(getattr(control, name).numpy(), getattr(direct, name).numpy(), atol=1e-13), name


# ---------------------------------------------------------------------------------------------
# 3. colliders on the roots' path


def test_a_turning_head_collider_and_its_roots_move_together_inside_every_frame(tmp_path, monkeypatch):
    """A sphere "head" and a strand rooted on it under one animated Xform, turning +-30 degrees about
    the vertical at 1 Hz and bobbing 2 cm: a point fixed to the head is a point fixed to the head
    at every substep, so each root, seen from the collider's pose of that substep, stays where it
    was authored. With the collider moving linearly between frame poses while the roots follow
    the C1 path, they parted mid-frame by about 1/8 of a frame's change of velocity times the frame
    (~4e-4 m here); on one path they agree to the interpolations' O(T^4)."""
    from scipy.spatial.transform import Rotation
    from usd_stages import add_curves, animated_xform, chain, new_stage
    from test_usd_features import sphere_collider

    from dftl_warp.features.step import FeatureStep

    frames = 12
    stage = new_stage(tmp_path / "head.usda", start=1, end=1 + frames, fps=FPS)
    phase = lambda f: 2 * np.pi * (f - 1) / FPS  # noqa: E731
    animated_xform(stage, "/World/Head",
                   translate={f: (0.0, 0.02 * np.sin(phase(f)), 0.0) for f in range(1, frames + 2)},
                   rotate_y={f: 30.0 * np.sin(phase(f)) for f in range(1, frames + 2)})
    sphere_collider(stage, "/World/Head/Skull", 0.1)
    root_local = np.array([0.0, 0.0, 0.102])
    add_curves(stage, "/World/Head/Hair", chain(9, 0.01, direction=(0.0, 0.0, 1.0), origin=root_local), [9])
    stage.Save()

    seen = []
    pose_and_bounds = FeatureStep.pose_and_bounds

    def recording(self, state_in, control, root_alpha, grid=True):
        pose_and_bounds(self, state_in, control, root_alpha, grid)
        pose = control.features.colliders.pose.numpy()[0].astype(np.float64)
        x0, x1, d0, d1 = (getattr(control, n).numpy()[0].astype(np.float64)
                          for n in ("root_start", "root_end", "root_deviation_start", "root_deviation_end"))
        root = paths(x0, x1, d0, d1, [float(root_alpha)])[0][0]   # the Control's path (root_on_path)
        seen.append(Rotation.from_quat(pose[3:]).inv().apply(root - pose[:3]))

    monkeypatch.setattr(FeatureStep, "pose_and_bounds", recording)
    summary = dw.simulate_usd(str(tmp_path / "head.usda"), str(tmp_path / "out.usdc"), device="cpu",
                              substeps=4, precision="float64")
    assert summary.colliders == 1 and len(seen) == 4 * frames
    assert not any("linearly" in w for w in summary.warnings), summary.warnings  # no path note now
    worst = np.abs(np.array(seen) - root_local).max()
    # measured (2-core CPU VM, 2026-11-24): 6.4e-6 m at the shot's ends (one-sided differences),
    # at most 3.6e-6 inside; the collider linear between its frame poses: 4.5e-4 m. What is left is
    # the two interpolations' own O(T^4) error (the roots' Hermite curve of the transform's matrix
    # is not quite a rotation mid-frame, the collider's normalised quaternion curve is): about
    # r |d4 theta / dt4| T^4 / 384 = 6e-7 m here
    assert worst < 1e-5, worst
