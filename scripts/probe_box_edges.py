#!/usr/bin/env python3
"""How deep hair goes into a box pushed through it, at every substep, and why.

An 8 cm box (optionally turned about an axis, and turning about it at ``--spin`` rad/s) moves along
+x at each speed through a patch of hanging strands (16 points, 2 cm apart, hair radius 50 um): a
box mesh as a deforming mesh (its points set once a frame, ``set_mesh_points``) or by its pose
(``set_collider_poses``), or the analytic ``Box`` by its pose (``analytic``), at the default 8
substeps, for each ``Colliders(iterations=...)``. Printed per configuration: the deepest any
non-root particle lies inside the box over all substeps (mm, by the box's analytic signed distance
where the simulation puts it, not by the collider code), and the number of *first entries* (a
particle more than 2 hair radii inside whose leader is outside, both outside the substep before).
``--why`` prints the deepest first entries: where the particle is in the box's frame, where it
was, its leader, and the leader's height above the contact plane of the particle's nearest face;
below minus the rest length (2 cm) no point at the rest length clears that face, the mechanism of
the edge bug fixed in ``kernels/features/mesh.py`` and for the analytic box in
``kernels/features/analytic.py`` (docs/features.md, "Around the edges of a moving mesh"): before
it, 17-20 mm deep at 1-2 m/s (the analytic box 5.3-6.1 mm); now nothing behind the surface.
``--sdf`` collides the mesh box through its signed distance field (5 mm cells; a deforming box moving
more than its depth band a frame is collided by exact queries instead, warned): before the field's
edge fix (docs/features.md, "Around the edges, through the field"), 11.5 mm deep at 2 m/s by pose.

    python scripts/probe_box_edges.py [--kinds deforming,pose,analytic] [--speeds 1,2] [--iterations 2,4]
        [--turn AX,AY,AZ,RAD] [--spin RAD_PER_S] [--strands 3] [--frames 12] [--why] [--sdf]
"""
import argparse

import numpy as np

import dftl_warp as dw
from dftl_warp import features as F

FPS, SUBSTEPS, HALF, RADIUS, SEGMENT = 24, 8, 0.04, 5e-5, 0.02


def box_mesh(h):
    p = np.array([[x, y, z] for x in (-h, h) for y in (-h, h) for z in (-h, h)])
    quads = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    return p, np.array([t for a, b, c, d in quads for t in ((a, b, c), (a, c, d))])


def turn(axis, angle):
    """Rotation matrix and quaternion (x, y, z, w) of ``angle`` rad about ``axis``."""
    a = np.asarray(axis, float) / np.linalg.norm(axis)
    k = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    return np.eye(3) + np.sin(angle) * k + (1 - np.cos(angle)) * k @ k, np.r_[a * np.sin(angle / 2), np.cos(angle / 2)]


def local_distance(q):
    """Signed distance to the box (m) of points in its frame, and the outward normal of the
    nearest face's plane for points inside (the face the closest-point query answers)."""
    d = np.abs(q) - HALF
    dist = np.linalg.norm(np.maximum(d, 0), axis=1) + np.minimum(d.max(1), 0)
    axis = d.argmax(1)
    normal = np.zeros_like(q)
    normal[np.arange(len(q)), axis] = np.sign(q[np.arange(len(q)), axis])
    return dist, normal


def run(kind, speed, iterations, axis, angle, spin, strands, frames, sdf=False):
    xs = np.linspace(-0.02, 0.02, strands)
    n = strands * strands
    pts = np.concatenate([np.stack([np.full(16, x), -SEGMENT * np.arange(16), np.full(16, z)], 1)
                          for x in xs for z in xs])
    box, tris = box_mesh(HALF)
    centre = lambda t: np.array([-0.07 + speed * t, -0.2, 0.0])  # noqa: E731
    rotation = lambda t: turn(axis, angle + spin * t)  # noqa: E731  (matrix, quaternion)
    rot, quat = rotation(0.0)
    field = dict(sdf=True, sdf_cell=0.005) if sdf else {}
    if kind == "deforming":
        shape = F.TriangleMesh(points=box @ rot.T + centre(0.0), indices=tris, **field)
    elif kind == "analytic":
        shape = F.Box(half_extents=(HALF, HALF, HALF), position=centre(0.0), rotation=quat)
    else:
        shape = F.TriangleMesh(points=box, indices=tris, position=centre(0.0), rotation=quat, **field)
    model = dw.Model.from_strands(pts, [16] * n, widths=2 * RADIUS, device="cpu",
                                  features=[F.Colliders([shape], iterations=iterations)])
    solver = dw.DFTLSolver(model, gravity=(0.0, -9.81, 0.0))
    state, control = solver.state(), model.control()
    free = np.ones(16 * n, bool)
    free[::16] = False
    worst, entries = 0.0, []
    q_prev = (model.points_from_device(state.positions) - centre(0.0)) @ rot
    d_prev = local_distance(q_prev)[0]
    for f in range(frames):
        t0, t1 = f / FPS, (f + 1) / FPS
        if kind == "deforming":
            control.features.set_mesh_points(0, box @ rotation(t1)[0].T + centre(t1))
        else:
            control.features.set_collider_poses([np.r_[centre(t0), rotation(t0)[1]]],
                                                 [np.r_[centre(t1), rotation(t1)[1]]])
        for k in range(SUBSTEPS):
            solver.step(state, state, control, 1.0 / FPS / SUBSTEPS, (k + 1) / SUBSTEPS)
            t = t0 + (k + 1) / SUBSTEPS / FPS       # the pose's slerp about a fixed axis: the angle is linear
            q = (model.points_from_device(state.positions) - centre(t)) @ rotation(t)[0]
            d, normal = local_distance(q)
            worst = max(worst, -float(d[free].min()))
            for i in np.flatnonzero(free & (d < -2 * RADIUS)):
                lead_ok = i % 16 == 1 or (d[i - 1] >= -2 * RADIUS and d_prev[i - 1] >= -2 * RADIUS)
                if d_prev[i] >= -2 * RADIUS and lead_ok:
                    plane = q[i] + (RADIUS - d[i]) * normal[i]
                    entries.append((f, k, i, -d[i], q[i], q_prev[i], q[i - 1], float((q[i - 1] - plane) @ normal[i])))
            q_prev, d_prev = q, d
    return worst, entries


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--speeds", default="1,2", help="m/s, comma separated")
    ap.add_argument("--iterations", default="2,4", help="Colliders iterations, comma separated")
    ap.add_argument("--turn", default="0,0,1,0", help="the box's rotation: axis x,y,z and angle (rad)")
    ap.add_argument("--spin", type=float, default=0.0,
                    help="the box turns about the --turn axis at this rate (rad/s); a deforming mesh's points "
                         "move on chords within a frame, up to r (1 - cos(spin / 48)) off the turned box the "
                         "depth is taken from")
    ap.add_argument("--kinds", default="deforming,pose,analytic", help="deforming, pose (box meshes), analytic (Box)")
    ap.add_argument("--strands", type=int, default=3, help="strands per side of the square patch")
    ap.add_argument("--frames", type=int, default=12)
    ap.add_argument("--why", action="store_true", help="print the deepest first entries")
    ap.add_argument("--sdf", action="store_true", help="collide through the box's signed distance field (5 mm cells)")
    a = ap.parse_args()
    ax, ay, az, angle = (float(v) for v in a.turn.split(","))
    np.set_printoptions(precision=2, suppress=True)
    for iterations in (int(v) for v in a.iterations.split(",")):
        for speed in (float(v) for v in a.speeds.split(",")):
            for kind in a.kinds.split(","):
                worst, entries = run(kind, speed, iterations, (ax, ay, az), angle, a.spin, a.strands, a.frames,
                                     a.sdf)
                print(f"iterations {iterations} {kind:9s} {speed:4.2f} m/s: deepest {worst * 1e3:6.2f} mm, "
                      f"first entries {len(entries)}", flush=True)
                for f, k, i, depth, q, was, lead, height in sorted(entries, key=lambda e: -e[3])[:3] if a.why else []:
                    print(f"    frame {f} substep {k} strand {i // 16} point {i % 16}: {depth * 1e3:.2f} mm in at "
                          f"{q * 1e3} mm (was {was * 1e3}), leader {lead * 1e3}, leader's height above the nearest "
                          f"face's contact plane {height * 1e3:.2f} mm (rest {SEGMENT * 1e3:g})")


if __name__ == "__main__":
    main()
