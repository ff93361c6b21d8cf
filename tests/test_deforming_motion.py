"""A deforming collider mesh (a point cache: its points set once a frame) moves inside the frame.

Before, its points jumped to the next frame's at the frame's start: a box that moved more than its
depth band (1.4 mm for an 8 cm box, 0.03 m/s at 24 fps) in a frame passed through hanging hair
without touching it. Now its points are interpolated every substep and the continuous test carries
the particle's start with the surface, so a deforming box pushes hair as the same box moved by its
pose does; a mesh with a signed distance field keeps the field while it moves less than its band
in a frame and collides through the exact queries (warned once) in frames it moves farther.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

import dftl_warp as dw
from dftl_warp import features as F
from dftl_warp.features.colliders import ColliderApproximationWarning

FPS, SUBSTEPS = 24, 8          # the default substeps
HALF = 0.04                    # the box's half extent (an 8 cm box)
RADIUS = 5e-5                  # hair radius
TRAVEL = 0.12                  # the box's front face goes from 3 cm before the hair to 5 cm past it
Y = -0.2                       # the box's centre height, 20 cm below the roots


def box_mesh(h):
    p = np.array([[x, y, z] for x in (-h, h) for y in (-h, h) for z in (-h, h)])
    quads = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    return p, np.array([t for a, b, c, d in quads for t in ((a, b, c), (a, c, d))])


def hanging_hair():
    """9 strands of 30 cm (16 points, 2 cm apart) hanging straight down, roots 2 cm apart."""
    pts = np.concatenate([np.stack([np.full(16, x), -0.02 * np.arange(16), np.full(16, z)], 1)
                          for x in (-0.02, 0.0, 0.02) for z in (-0.02, 0.0, 0.02)])
    return pts, [16] * 9


def centre_at(speed):
    """The box's centre at time t: from x = -7 cm at ``speed`` m/s, stopping after TRAVEL."""
    return lambda t: np.array([-0.07 + speed * min(t, TRAVEL / speed), Y, 0.0])


def move_box(control, deforming, box, centre, t0, t1):
    """The frame from ``t0`` to ``t1`` (s) of a box whose centre is ``centre(t)``: its points at
    ``t1`` (a deforming mesh) or its poses at both ends (moved by its pose)."""
    if deforming:
        control.features.set_mesh_points(0, box + centre(t1))
    else:
        control.features.set_collider_poses([np.r_[centre(t0), 0, 0, 0, 1]], [np.r_[centre(t1), 0, 0, 0, 1]])


def push(kind, speed, sdf=False, frames=None):
    """Hair after a box moved through it (``kind``: "deforming", its points set every frame, or
    "pose", its pose animated) and 6 frames more, the box's final centre, and the warnings."""
    pts, counts = hanging_hair()
    box, tris = box_mesh(HALF)
    centre = centre_at(speed)
    deforming = kind == "deforming"
    shape = F.TriangleMesh(points=box + centre(0.0) if deforming else box, indices=tris, sdf=sdf,
                           sdf_cell=0.005 if sdf else None, position=np.zeros(3) if deforming else centre(0.0))
    model = dw.Model.from_strands(pts, counts, widths=2 * RADIUS, device="cpu", features=[F.Colliders([shape])])
    solver = dw.DFTLSolver(model, gravity=(0.0, -9.81, 0.0))
    state, control = solver.state(), model.control()
    frames = frames or int(np.ceil(TRAVEL / speed * FPS)) + 6
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", ColliderApproximationWarning)
        for f in range(frames):
            move_box(control, deforming, box, centre, f / FPS, (f + 1) / FPS)
            solver.advance(state, control, 1.0 / FPS / SUBSTEPS, SUBSTEPS)
    x = model.points_from_device(state.positions)
    return np.delete(x, np.arange(9) * 16, axis=0), centre(frames / FPS), control, caught


def box_distance(x, c, half=HALF):
    q = np.abs(x - c) - np.asarray(half)
    return np.linalg.norm(np.maximum(q, 0.0), axis=1) + np.minimum(q.max(axis=1), 0.0)


def assert_pushed(x, c):
    """Every particle outside the box (to its hair radius and 0.1 mm), none behind its front face at
    its height (tunnelled through, or inside), and the hair pushed ahead of the front face."""
    assert box_distance(x, c).min() > -(RADIUS + 1e-4), box_distance(x, c).min()
    level = (np.abs(x[:, 1] - c[1]) < HALF) & (np.abs(x[:, 2] - c[2]) < HALF)
    front = c[0] + HALF
    assert level.any() and np.all(x[level, 0] >= front - RADIUS - 1e-4), np.sort(x[level, 0] - front)[:5]


@pytest.mark.parametrize("speed", [1.0, 2.0])
def test_a_deforming_box_pushes_hanging_hair_as_a_moved_one_does(speed):
    """At 1 and 2 m/s (42 and 83 mm a frame, 30 and 60 times the box's depth band) the deforming box
    pushes the hair ahead of it, as the same box moved by its pose does; before, the hair stayed
    where it hung and the box went through it."""
    for kind in ("pose", "deforming"):
        x, c, _, _ = push(kind, speed)
        assert_pushed(x, c)


def test_a_slow_deforming_box_pushes_hair_as_before():
    """At 0.03 m/s (1.25 mm a frame, within the depth band) the box pushed the hair before too."""
    x, c, _, caught = push("deforming", 0.03, frames=60)
    assert c[0] + HALF > 0.04     # it went 4.5 cm into the hair
    assert_pushed(x, c)
    assert not caught


def test_a_field_follows_a_slow_mesh_and_hands_a_fast_one_to_the_exact_queries():
    """With a signed distance field: a box moving less than its band a frame keeps its field (built
    at the frame's end, no warning); at 2 m/s its frames collide through the interpolated exact
    queries, warned once, and the hair is pushed, not passed through."""
    x, c, control, caught = push("deforming", 0.03, sdf=True, frames=60)
    assert_pushed(x, c)
    meshes = control.features.colliders.kind_data["meshes"]
    assert meshes.fields.grids.numpy()[0]["cell"] > 0 and not meshes.moving and not caught
    x, c, control, caught = push("deforming", 2.0, sdf=True)
    assert_pushed(x, c)
    moving = [w for w in caught if "depth band" in str(w.message)]
    assert len(moving) == 1, [str(w.message) for w in caught]


def test_after_resync_a_mesh_moves_from_the_start_it_is_given():
    """After a saved state is restored (resync) the mesh is where the frame's ``start`` says, not
    where it was last set: a box set far left of the hair, then (resynced) moved 1 cm a frame far
    right of it, never sweeps through it; without the start it is placed at the frame's points."""
    pts, counts = hanging_hair()
    box, tris = box_mesh(HALF)
    model = dw.Model.from_strands(pts, counts, widths=2 * RADIUS, device="cpu",
                                  features=[F.Colliders([F.TriangleMesh(points=box + [-0.3, Y, 0.0], indices=tris)])])
    solver = dw.DFTLSolver(model, gravity=(0.0, -9.81, 0.0))
    state, control = solver.state(), model.control()
    for start in (0.3, None):
        control.features.resync()
        here = None if start is None else box + [start, Y, 0.0]
        control.features.set_mesh_points(0, box + [0.31, Y, 0.0], start=here)
        solver.advance(state, control, 1.0 / FPS / SUBSTEPS, SUBSTEPS)
        x = model.points_from_device(state.positions)
        assert np.abs(x[:, 0] - pts[:, 0]).max() < 1e-6    # the hair hangs untouched
        control.features.set_mesh_points(0, box + [-0.3, Y, 0.0])   # last set far left again


def test_the_cache_qc_measures_hair_inside_a_moving_mesh_where_it_is():
    """The QC's depth (dftl_warp.output.qc.ColliderDepth) of hair inside a mesh moving within its
    frame is the distance to its surface now, not carried with the surface's motion: mid-frame,
    strands hanging through a flat box moving sideways read its exact depth (in hair radii; carried
    with the motion, friction against it would shift the deepest point sideways, 4% deeper)."""
    import warp as wp

    from dftl_warp.output.qc import ColliderDepth

    pts, counts = hanging_hair()
    box, tris = box_mesh(HALF)
    box = box * [1.0, 0.25, 1.0]                                   # 1 cm half height
    model = dw.Model.from_strands(pts, counts, widths=2 * RADIUS, device="cpu",
                                  features=[F.Colliders([F.TriangleMesh(points=box + [0.0, Y, 0.0], indices=tris)])])
    control = model.control()
    control.features.set_mesh_points(0, box + [0.02, Y, 0.0])     # 2 cm sideways in the frame
    cc = control.features.colliders
    cc.advance(0.25)
    cc.advance(0.5)                                                # mid-frame: the box at x = 1 cm
    probe = ColliderDepth(model, control, RADIUS)
    penetration = wp.zeros(1, dtype=wp.float64, device="cpu")
    probe.launch(model.state(), wp.zeros(model.num_strands, dtype=wp.int32, device="cpu"), penetration)
    d = box_distance(pts, np.array([0.01, Y, 0.0]), (HALF, 0.25 * HALF, HALF))
    d[np.arange(9) * 16] = np.inf
    assert penetration.numpy()[0] == pytest.approx((RADIUS - d.min()) / RADIUS, rel=1e-3)
