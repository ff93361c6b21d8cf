"""The elastic solver with roots bound to a deforming mesh (``F.RootBinding``): the clamp ghost behind
each root turns with its bound triangle's frame (edge 0 and the normal: ``F = [t, n x t, n]``,
``t`` along edge 0, ``n`` the unit normal), ``ghost = root + F F_rest^T (ghost_rest - root_rest)``.

Zero gravity: the authored (rest) shape is then the equilibrium in any orientation, so once settled
a strand must be its rest shape turned by its root frame, exactly. The root frame is the triangle
frame's rotation (``kernels/solvers/elastic.py``: the clamp's rotation, then the minimal rotation
onto the ghost's direction on the path), so the curl turns about its first segment with the
triangle too. CPU, float64."""

from __future__ import annotations

import numpy as np
import pytest
from pxr import Sdf, UsdGeom, UsdPhysics, Vt
from usd_stages import add_curves, animated_xform, composed_samples, new_stage

import dftl_warp as dw
from dftl_warp import features as F
from dftl_warp.core.state import frame_velocity

R = 40e-6          # 80 um hair
FPS = 24.0
SUB = 32
N = 12             # segments per strand
TURN, HOLD = 12, 36  # frames of the mesh's motion, then held (1.5 s: the strand settles to about 1e-8 L)
#: the scalp: a 4 cm quad in the xz-plane (two triangles; triangle 0 has the normal +y)
SCALP = np.array([[-0.02, 0.0, 0.02], [0.02, 0.0, 0.02], [0.02, 0.0, -0.02], [-0.02, 0.0, -0.02]])
TRIANGLES = np.array([[0, 1, 2], [0, 2, 3]])
WEIGHTS = np.array([0.2, 0.3, 0.5])
#: the authored first direction: out of the scalp at about 45 degrees
D0 = np.array([0.6, 0.7, 0.4]) / np.linalg.norm([0.6, 0.7, 0.4])


def rotation(axis, angle: float) -> np.ndarray:
    """Rotation by ``angle`` (rad) about ``axis`` (Rodrigues)."""
    k = np.asarray(axis, float) / np.linalg.norm(axis)
    K = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.eye(3) + np.sin(angle) * K + (1.0 - np.cos(angle)) * K @ K


def minimal_rotation(a, b) -> np.ndarray:
    """The rotation taking unit ``a`` to unit ``b`` about ``a x b`` (a, b not opposite)."""
    c = np.cross(a, b)
    K = np.array([[0.0, -c[2], c[1]], [c[2], 0.0, -c[0]], [-c[1], c[0], 0.0]])
    return np.eye(3) + K + K @ K / (1.0 + a @ b)


def styled_strand(root, d0, n=N, radius=0.006, turns=1.1, rise=0.012) -> np.ndarray:
    """A curl of ``n`` equal segments (a helix, about 4 cm) leaving ``root`` along ``d0``."""
    phi = np.linspace(0.0, 2 * np.pi * turns, n + 1)
    local = np.stack([radius * np.sin(phi), rise * phi / (2 * np.pi * turns), radius * (1 - np.cos(phi))], 1)
    first = (local[1] - local[0]) / np.linalg.norm(local[1] - local[0])
    return root + local @ minimal_rotation(first, d0).T


def smooth(u: float) -> float:
    u = min(max(u, 0.0), 1.0)
    return u * u * (3.0 - 2.0 * u)


def bound_strand(rest):
    """Model (float64, bound to triangle 0 at WEIGHTS), elastic solver at zero gravity, State, Control."""
    model = dw.Model.from_strands(rest, [len(rest)], precision="float64", device="cpu",
                                  features=[F.RootBinding(SCALP, TRIANGLES, triangles=[0], weights=[WEIGHTS])])
    solver = dw.make_solver(model, "elastic", radius=R, gravity=(0.0, 0.0, 0.0))
    return model, solver, solver.state(), model.control()


def drive(model, solver, state, control, mesh_at, frames: int) -> float:
    """Frames 0..frames of the mesh ``mesh_at(frame)``: roots and clamps on the C1 path (the mesh
    points' velocities from the differences ``simulate`` takes); the largest relative segment-length
    error seen after any frame."""
    T = 1.0 / FPS
    rest = np.linalg.norm(np.diff(model.points_from_device(state.positions), axis=0), axis=1)
    worst = 0.0
    for f in range(frames):
        control.bind_roots(mesh_at(f), mesh_at(f + 1), velocity_start=frame_velocity(mesh_at, f, 0, frames, T),
                           velocity_end=frame_velocity(mesh_at, f + 1, 0, frames, T), frame_duration=T)
        solver.bind_clamps(control)
        solver.advance(state, control, T / SUB, SUB)
        x = model.points_from_device(state.positions)
        worst = max(worst, np.abs(np.linalg.norm(np.diff(x, axis=0), axis=1) / rest - 1).max())
    return worst


@pytest.mark.parametrize("axis", ["perpendicular", "normal"])
def test_a_styled_strand_turns_with_a_rigidly_turning_scalp(axis):
    """The scalp turns 60 degrees about a pivot 5 cm below it (a head), then holds. About an axis
    perpendicular to the authored direction and about the scalp's normal (a head turn: the curl
    must turn about its own first segment too) the settled strand is its rest shape turned with
    the scalp. Segment lengths stay exact throughout."""
    root = WEIGHTS @ SCALP[TRIANGLES[0]]
    rest = styled_strand(root, D0)
    L = np.linalg.norm(np.diff(rest, axis=0), axis=1).sum()
    k = np.cross(D0, [0.0, 1.0, 0.0]) if axis == "perpendicular" else np.array([0.0, 1.0, 0.0])
    pivot = np.array([0.0, -0.05, 0.0])

    def turn(f):
        return rotation(k, np.radians(60.0) * smooth(f / TURN))

    model, solver, state, control = bound_strand(rest)
    stretch = drive(model, solver, state, control, lambda f: (SCALP - pivot) @ turn(f).T + pivot, TURN + HOLD)
    Q = turn(TURN)
    x = model.points_from_device(state.positions)
    root_now = Q @ (root - pivot) + pivot
    frame = Q
    direction = (x[1] - x[0]) / np.linalg.norm(x[1] - x[0])
    assert np.abs(x[0] - root_now).max() < 1e-12
    # measured (2-core CPU VM, 2026-11-24): direction 2.0e-9 / 1.7e-10, shape 1.6e-8 L / 1.3e-9 L
    # (perpendicular / normal), still falling (the frames relax by one sweep per substep)
    assert np.abs(direction - Q @ D0).max() < 1e-7
    assert np.abs(x - (root_now + (rest - root) @ frame.T)).max() < 1e-6 * L
    assert stretch < 1e-12


def scalp_deformed(s: float, tilt=np.radians(40.0), spin=np.radians(30.0)) -> np.ndarray:
    """The scalp at ``s`` in [0, 1] of a non-rigid motion: triangle 0's edge 0 stretched 1.5x, its
    third point sheared 1.2 cm along edge 0 and tilted ``tilt`` about edge 0, all turned ``spin``
    about +y and moved 6 mm. Triangle 0's frame (edge 0, normal) then turns by Ry(spin) Rx(tilt):
    stretch and shear along edge 0 do not turn it."""
    p0 = SCALP[0] + s * np.array([0.004, 0.002, -0.004])
    spin_now = rotation([0.0, 1.0, 0.0], s * spin)
    e0 = (1.0 + 0.5 * s) * (SCALP[1] - SCALP[0])
    e1 = np.array([0.04 + 0.012 * s, 0.04 * np.sin(s * tilt), -0.04 * np.cos(s * tilt)])
    return p0 + np.stack([np.zeros(3), e0, e1, SCALP[3] - SCALP[0]]) @ spin_now.T


def test_the_clamp_follows_a_deforming_triangle():
    """Triangle 0 stretched, sheared and tilted (not a rigid motion), then held: the root rides its
    barycentric point, the first segment leaves along Ry(spin) Rx(tilt) d0 (the triangle frame's
    turn), the strand settles to its rest shape turned by that frame's rotation (its twist about
    the first segment included), and segment lengths stay exact throughout."""
    root = WEIGHTS @ SCALP[TRIANGLES[0]]
    rest = styled_strand(root, D0)
    L = np.linalg.norm(np.diff(rest, axis=0), axis=1).sum()
    model, solver, state, control = bound_strand(rest)
    stretch = drive(model, solver, state, control, lambda f: scalp_deformed(smooth(f / TURN)), TURN + HOLD)
    turn = rotation([0.0, 1.0, 0.0], np.radians(30.0)) @ rotation([1.0, 0.0, 0.0], np.radians(40.0))
    x = model.points_from_device(state.positions)
    root_now = WEIGHTS @ scalp_deformed(1.0)[TRIANGLES[0]]
    direction = (x[1] - x[0]) / np.linalg.norm(x[1] - x[0])
    assert np.abs(x[0] - root_now).max() < 1e-12
    # measured (2-core CPU VM, 2026-11-24): direction 6.7e-10, shape 3.3e-9 L
    assert np.abs(direction - turn @ D0).max() < 1e-7
    assert np.abs(x - (root_now + (rest - root) @ turn.T)).max() < 1e-6 * L
    assert stretch < 1e-12


def ghost_at(solver, state, control, alpha: float) -> np.ndarray:
    """Where the clamp ghost is at ``alpha`` of the frame (a step to that point of the path)."""
    out = state.clone()
    solver.step(state, out, control, 1e-4, alpha)
    return out.clamps.numpy()[0].astype(np.float64)


@pytest.mark.parametrize("motion", ["rigid", "deforming"])
def test_the_clamp_path_has_the_ghosts_velocity(motion):
    """The C1 path's tangent at a frame's start is the ghost's velocity for the mesh points'
    velocities: for a scalp turning at 2 rad/s about a pivot, omega x (ghost - pivot); for the
    deforming scalp, the central difference of the ghost over the motion (converged: step 1e-6 s)."""
    root = WEIGHTS @ SCALP[TRIANGLES[0]]
    model, solver, state, control = bound_strand(styled_strand(root, D0))
    T, t0 = 1.0 / FPS, 0.3
    pivot, omega = np.array([0.0, -0.05, 0.0]), 2.0 * np.array([0.3, 0.2, 0.9]) / np.linalg.norm([0.3, 0.2, 0.9])
    if motion == "rigid":
        def mesh_at(t):
            return (SCALP - pivot) @ rotation(omega, np.linalg.norm(omega) * t).T + pivot

        def mesh_rate(t):
            return np.cross(omega, mesh_at(t) - pivot)
    else:
        def mesh_at(t):
            return scalp_deformed(t)

        def mesh_rate(t, h=1e-6):
            return (mesh_at(t + h) - mesh_at(t - h)) / (2 * h)

    def ghost_of(t):
        control.bind_roots(mesh_at(t))
        solver.bind_clamps(control)
        return ghost_at(solver, state, control, 0.0)

    if motion == "rigid":
        expected = np.cross(omega, ghost_of(t0) + model.origin - pivot)
    else:
        expected = (ghost_of(t0 + 1e-6) - ghost_of(t0 - 1e-6)) / 2e-6
    control.bind_roots(mesh_at(t0), mesh_at(t0 + T), velocity_start=mesh_rate(t0), velocity_end=mesh_rate(t0 + T),
                       frame_duration=T)
    solver.bind_clamps(control)
    eps = 1e-4
    g = [ghost_at(solver, state, control, a) for a in (0.0, eps, 2 * eps)]
    velocity = (-3 * g[0] + 4 * g[1] - g[2]) / (2 * eps * T)   # d/dt at the frame's start, error O(eps^2)
    # measured (2-core CPU VM, 2026-11-24): 3e-11 relative (rigid), 6e-11 (deforming)
    assert np.linalg.norm(velocity - expected) < 1e-6 * np.linalg.norm(expected), (velocity, expected)


def test_a_prim_with_widths_bound_to_a_turning_scalp_runs_elastic(tmp_path):
    """Through ``simulate_usd``: a curl of 80 um hair bound (``dftl:rootMesh``) to a scalp under an
    Xform that turns 60 degrees about +y (a head turning), zero gravity. The prim runs elastic with
    no fallback warning, and its last frame is the authored curl turned with the head (the turn's
    axis is perpendicular to the authored first direction, so the clamp carries the full turn)."""
    stage = new_stage(tmp_path / "in.usda", start=1, end=1 + TURN + HOLD)
    physics = UsdPhysics.Scene.Define(stage, "/World/Physics")
    physics.CreateGravityMagnitudeAttr(0.0)
    head = animated_xform(stage, "/World/Head", rotate_y={1: 0.0, 1 + TURN: 60.0})
    scalp = UsdGeom.Mesh.Define(stage, "/World/Head/Scalp")
    scalp.CreateFaceVertexCountsAttr(Vt.IntArray([4]))
    scalp.CreateFaceVertexIndicesAttr(Vt.IntArray([0, 1, 2, 3]))
    # the scalp in the xy-plane, 3 cm in front of the head's axis; the curl leaves it at 45 degrees in xz
    quad = np.array([[-0.02, -0.02, 0.03], [0.02, -0.02, 0.03], [0.02, 0.02, 0.03], [-0.02, 0.02, 0.03]])
    scalp.CreatePointsAttr(Vt.Vec3fArray.FromNumpy(quad.astype(np.float32)))
    d0 = np.array([1.0, 0.0, 1.0]) / np.sqrt(2.0)
    rest = styled_strand(np.array([0.001, 0.002, 0.03]), d0).astype(np.float32).astype(np.float64)
    hair = add_curves(stage, "/World/Hair", rest, [len(rest)], widths=2 * R, bending=None)
    hair.GetPrim().CreateRelationship("dftl:rootMesh", custom=True).AddTarget(Sdf.Path("/World/Head/Scalp"))
    stage.Save()
    assert head.GetPrim().IsValid()
    summary = dw.simulate_usd(str(tmp_path / "in.usda"), str(tmp_path / "out.usdc"), device="cpu",
                              precision="float64", substeps=SUB)
    assert summary.groups[0]["solver"] == "elastic"
    assert not any("plain DFTL chain" in w for w in summary.warnings + summary.run_warnings), summary.warnings
    x = composed_samples(tmp_path / "out.usdc", "/World/Hair")[float(1 + TURN + HOLD)]
    turned = rest @ rotation([0.0, 1.0, 0.0], np.radians(60.0)).T
    L = np.linalg.norm(np.diff(rest, axis=0), axis=1).sum()
    # measured (2-core CPU VM, 2026-11-24): 1.1e-8 L (written as float32; the closest point is found
    # in float32)
    assert np.abs(x - turned).max() < 1e-6 * L


def test_a_degenerate_triangle_keeps_the_authored_clamp_with_a_warning():
    """A root bound to a triangle without a frame (zero area): its clamp moves with the root without
    turning, and a warning says so."""
    flat = np.array([[0.0, 0.0, 0.0], [0.02, 0.0, 0.0], [0.04, 0.0, 0.0]])
    root = np.array([0.01, 0.0, 0.0])
    rest = styled_strand(root, D0)
    model = dw.Model.from_strands(rest, [len(rest)], precision="float64", device="cpu",
                                  features=[F.RootBinding(flat, [[0, 1, 2]], triangles=[0], weights=[[0.5, 0.5, 0.0]])])
    solver = dw.make_solver(model, "elastic", radius=R, gravity=(0.0, 0.0, 0.0))
    state, control = solver.state(), model.control()
    moved = flat @ rotation([0.0, 0.0, 1.0], 0.5).T + [0.0, 0.01, 0.0]
    control.bind_roots(moved)
    with pytest.warns(UserWarning, match="1 strand is bound to triangles with no frame"):
        solver.bind_clamps(control)
    ghost = ghost_at(solver, state, control, 0.0) + model.origin
    assert np.abs(ghost - (0.5 * (moved[0] + moved[1]) + solver.authored_clamps[0] - root)).max() < 1e-15


def test_a_curl_under_a_head_turning_about_its_first_segment_turns_with_it(tmp_path):
    """Through ``simulate_usd``, no root mesh: a curl of 80 um hair whose first segment points up
    (+y), in a prim under an Xform turning 60 degrees about +y (a head turn about the first segment's
    own axis), zero gravity. The clamp takes the prim's rotation, so the settled curl is the
    authored one turned with the head (with the minimal rotation alone it stayed unturned)."""
    stage = new_stage(tmp_path / "in.usda", start=1, end=1 + TURN + HOLD)
    physics = UsdPhysics.Scene.Define(stage, "/World/Physics")
    physics.CreateGravityMagnitudeAttr(0.0)
    animated_xform(stage, "/World/Head", rotate_y={1: 0.0, 1 + TURN: 60.0})
    root = np.array([0.01, 0.05, 0.0])
    rest = styled_strand(root, np.array([0.0, 1.0, 0.0])).astype(np.float32).astype(np.float64)
    add_curves(stage, "/World/Head/Hair", rest, [len(rest)], widths=2 * R, bending=None)
    stage.Save()
    summary = dw.simulate_usd(str(tmp_path / "in.usda"), str(tmp_path / "out.usdc"), device="cpu",
                              precision="float64", substeps=SUB)
    assert summary.groups[0]["solver"] == "elastic"
    x = composed_samples(tmp_path / "out.usdc", "/World/Head/Hair")[float(1 + TURN + HOLD)]
    # the written points are the prim's local ones: the curl is as authored in the head's frame
    L = np.linalg.norm(np.diff(rest, axis=0), axis=1).sum()
    assert np.abs(x - rest).max() < 1e-6 * L
