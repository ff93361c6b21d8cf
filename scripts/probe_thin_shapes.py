#!/usr/bin/env python3
"""How deep hair goes into thin analytic shapes pushed through it, at every substep, and how often
its segments straddle them.

A thin shape moves by its pose along +x through a patch of hanging strands (``--strands`` squared,
16 points ``--segments`` apart, roots staggered over one segment so that a thin shape meets some
particles and passes between others; hair radius 50 um), from 5 mm before the first strands, 10 cm
at each speed (whole frames: the pose is linear within a frame), then stands still for ``--rest``
frames; 8 substeps at 24 fps, DFTL (``--solver elastic``: the elastic solver),
``Colliders(iterations=...)``. The shape sits at the strands'
mid height, its top 1 cm below the roots at least (a root inside a collider is not the case here).
Shapes (``--shapes``): ``capsuleR`` a horizontal capsule of radius R mm and length 10 cm across
the motion (a finger, a strap), ``sphereR`` a sphere of radius R mm, ``plateX``/``plateY``/
``plateZ`` an ellipsoid of semi-axes 5 x 5 cm and 2 mm along X (face on to the motion), Y (a flat
horizontal plate, edge on) or Z (a vertical blade, edge on). Printed per configuration, measured by
the shape's analytic signed distance (numpy, not the collider code) where the simulation puts it at
that substep:

- ``deepest``: the deepest any non-root particle lies inside (mm, hair radii), and ``first entries``
  (a particle more than 2 hair radii inside, its leader outside, both outside the substep before);
  ``--why`` prints the deepest with its leader's height above the nearest point's contact plane
  (below minus the rest length no point at the rest length clears it: the convex-edge case of
  docs/features.md, "Around the edges of a moving mesh", which the smooth shapes met where they are
  thinner than a segment: before the entry answer of ``kernels/features/analytic.py``, 0.56-3.1 mm
  deep in 23 of the 48 default configurations; now none behind the surface);
- ``moved``: the farthest any particle got from where it hung (the shape pushed the hair);
- ``straddles``: segment-substeps whose two particles are outside the shape on opposite sides
  (their nearest points' normals more than 90 degrees apart) while the segment passes more than 2
  hair radii inside (docs/features.md, "Known limit: segments across thin parts"), the most at one
  substep and how many at the last substep;
- ``KE at rest``: the largest kinetic energy per unit mass (J/kg, mean over a strand's free
  particles) of any strand, and of the strands still straddling, over the last 2 frames (a
  chattering particle keeps it up); and the energy check's warning, if any, naming the strand and
  frame and whether that strand was within 1 mm of the shape then (beyond it, the energy came from
  the strand's own motion, not from a contact).

    python scripts/probe_thin_shapes.py [--shapes capsule1,capsule2,capsule3,sphere3,sphere5,plateX,plateY,plateZ]
        [--speeds 0.5,1,2] [--segments 0.005,0.02] [--strands 5] [--iterations 2] [--rest 24] [--why]
"""
import argparse
import re
import warnings

import numpy as np

import dftl_warp as dw
from dftl_warp import features as F
from dftl_warp.simulation.monitor import EnergyGrowthWarning, EnergyMonitor

FPS, SUBSTEPS, RADIUS, POINTS, TRAVEL = 24, 8, 5e-5, 16, 0.1
HALF_LENGTH, PLATE, THIN = 0.05, 0.05, 0.002


def ellipsoid_distance(q, e):
    """Exact signed distance (m) of points ``q`` (n, 3) to the ellipsoid of semi-axes ``e``: the
    closest point ``x_i = e_i^2 y_i / (t + e_i^2)`` with ``sum (e_i y_i / (t + e_i^2))^2 = 1`` for
    ``t`` in (-min e^2, |e y|], found by bisection in float64, and its outward normal."""
    e = np.asarray(e, float)
    y = np.maximum(np.abs(q), 1e-12 * e.min())
    lo = np.full(len(q), -e.min() ** 2)
    hi = np.maximum(np.linalg.norm(e * y, axis=1), 0.0)
    for _ in range(80):
        t = 0.5 * (lo + hi)
        f = (((e * y) / (t[:, None] + e * e)) ** 2).sum(1) - 1.0
        lo, hi = np.where(f > 0, t, lo), np.where(f > 0, hi, t)
    x = e * e * y / (0.5 * (lo + hi)[:, None] + e * e)
    d = np.linalg.norm(y - x, axis=1)
    inside = ((y / e) ** 2).sum(1) < 1.0
    n = x / (e * e)
    n = np.sign(q + (q == 0)) * n / np.linalg.norm(n, axis=1, keepdims=True)
    return np.where(inside, -d, d), n


def shape_of(name, position):
    """The shape named ``name`` at ``position``, its signed distance ``sdf(q) -> (d, n)`` in its own
    frame (m, outward normal) and its half extents (m)."""
    kind, size = name.rstrip("0123456789.XYZ"), name[len(name.rstrip("0123456789.XYZ")):]
    if kind == "capsule":
        r = float(size) * 1e-3
        shape = F.Capsule(radius=r, half_height=HALF_LENGTH, axis="Z", position=position)

        def sdf(q):
            a = q.copy()
            a[:, 2] -= np.clip(q[:, 2], -HALF_LENGTH, HALF_LENGTH)
            d = np.linalg.norm(a, axis=1)
            return d - r, a / np.maximum(d, 1e-30)[:, None]
        return shape, sdf, np.array([r, r, HALF_LENGTH])
    if kind == "sphere":
        r = float(size) * 1e-3
        shape = F.Sphere(radius=r, position=position)

        def sdf(q):
            d = np.linalg.norm(q, axis=1)
            return d - r, q / np.maximum(d, 1e-30)[:, None]
        return shape, sdf, np.full(3, r)
    if kind == "plate":
        e = np.full(3, PLATE)
        e["XYZ".index(size)] = THIN
        shape = F.Ellipsoid(radii=e, position=position)
        return shape, (lambda q: ellipsoid_distance(q, e)), e
    raise SystemExit(f"probe_thin_shapes.py: unknown shape {name!r} (capsuleR, sphereR, plateX/Y/Z)")


def hanging(strands, segment, span):
    """``strands`` x ``strands`` strands of POINTS points ``segment`` apart hanging along -y, x in
    +-1 cm and z in +-``span``, their roots staggered over one segment below y = 0 (their particles'
    heights spread evenly: a thin shape meets some particles and passes between others)."""
    xs, zs = np.linspace(-0.01, 0.01, strands), np.linspace(-span, span, strands)
    drop = segment * (np.arange(strands * strands) * 7 % (strands * strands)) / (strands * strands)
    return np.concatenate([np.stack([np.full(POINTS, x), -segment * np.arange(POINTS) - drop[j], np.full(POINTS, z)],
                                    1) for j, (x, z) in enumerate((x, z) for x in xs for z in zs)])


def run(name, speed, segment, strands, iterations, rest, observe=None, solver_name="dftl", split=None):
    """Measure one configuration (module docstring); ``observe(f, k, q, d)`` sees every substep;
    ``split``: a strand whose energy is logged after every frame in ``out["split"]`` (frame, the
    energy check's available energy, kinetic, gravitational above hanging, the rest (elastic), J/kg
    summed over its free particles, and its sharpest joint's turn in degrees)."""
    half = shape_of(name, np.zeros(3))[2]
    height = -max(0.5 * segment * (POINTS - 1), half[1] + 0.01)   # at mid strand, 1 cm below the roots at least
    moving = int(np.ceil(TRAVEL / speed * FPS))          # it stops at a frame's end: the pose is linear in each frame
    centre = lambda t: np.array([-0.015 - half[0] + speed * min(t, moving / FPS), height, 0.0])  # noqa: E731
    shape, sdf, _ = shape_of(name, centre(0.0))
    pts = hanging(strands, segment, min(0.8 * half[2], 0.02))
    n = strands * strands
    model = dw.Model.from_strands(pts, [POINTS] * n, widths=2 * RADIUS, device="cpu",
                                  features=[F.Colliders([shape], iterations=iterations)])
    solver = dw.make_solver(model, solver_name, gravity=(0.0, -9.81, 0.0))
    state, control = solver.state(), model.control()
    monitor = EnergyMonitor(solver, name, state, control=control, frame_duration=1.0 / FPS)
    free = np.ones(POINTS * n, bool)
    free[::POINTS] = False
    lead = np.flatnonzero(free) - 1
    s = np.linspace(0.0, 1.0, 17)[1:-1]
    out = dict(worst=0.0, entries=[], straddles=0, most=0, moved=0.0, ke=0.0, held=0, ke_held=0.0)
    near = np.zeros((moving + rest, n), bool)          # per frame, the strands within 1 mm of the shape
    d_prev = sdf(pts - centre(0.0))[0]
    frames = moving + rest
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", EnergyGrowthWarning)
        for f in range(frames):
            t0, t1 = f / FPS, (f + 1) / FPS
            control.features.set_collider_poses([np.r_[centre(t0), 0, 0, 0, 1]], [np.r_[centre(t1), 0, 0, 0, 1]])
            for k in range(SUBSTEPS):
                solver.step(state, state, control, 1.0 / FPS / SUBSTEPS, (k + 1) / SUBSTEPS)
                q = model.points_from_device(state.positions) - centre(t0 + (k + 1) / SUBSTEPS / FPS)
                d, normal = sdf(q)
                near[f] |= (d.reshape(n, POINTS)[:, 1:] < 1e-3).any(1)
                out["worst"] = max(out["worst"], -float(d[free].min()))
                out["moved"] = max(out["moved"], float(np.linalg.norm(q + centre(t0 + (k + 1) / SUBSTEPS / FPS)
                                                                      - pts, axis=1).max()))
                for i in np.flatnonzero(free & (d < -2 * RADIUS)):
                    if d_prev[i] >= -2 * RADIUS and d[i - 1] >= -2 * RADIUS and d_prev[i - 1] >= -2 * RADIUS:
                        plane = q[i] + (RADIUS - d[i]) * normal[i]
                        out["entries"].append((f, k, i, -d[i], q[i], q[i - 1], float((q[i - 1] - plane) @ normal[i])))
                mid = q[lead][:, None] + s[None, :, None] * (q[free] - q[lead])[:, None]
                inner = sdf(mid.reshape(-1, 3))[0].reshape(len(lead), len(s)).min(1)
                opposite = (normal[lead] * normal[free]).sum(1) < 0.0
                across = (d[lead] >= 0) & (d[free] >= 0) & (inner < -2 * RADIUS) & opposite
                out["straddles"] += int(across.sum())
                out["most"] = max(out["most"], int(across.sum()))
                if observe is not None:
                    observe(f, k, q, d)
                d_prev = d
            monitor.check(state, f)
            if split is not None:
                x = model.points_from_device(state.positions, relative=False).reshape(n, POINTS, 3)[split]
                v = model.points_from_device(state.velocities, relative=False).reshape(n, POINTS, 3)[split]
                kinetic = 0.5 * float((v[1:] ** 2).sum())
                gravity = 9.81 * float((x[1:, 1] - (x[0, 1] - segment * np.arange(1, POINTS))).sum())
                u = np.diff(x, axis=0)
                u /= np.linalg.norm(u, axis=1)[:, None]
                turn = float(np.degrees(np.arccos(np.clip((u[1:] * u[:-1]).sum(1), -1.0, 1.0))).max())
                available = float(monitor.verdicts()[0][split])
                out.setdefault("split", []).append((f, available, kinetic, gravity, available - kinetic - gravity, turn))
            if f >= frames - 2:
                v = model.points_from_device(state.velocities)
                ke = 0.5 * (v * v).sum(1)[free].reshape(n, POINTS - 1).mean(1)
                held = across.reshape(n, POINTS - 1).any(1)
                out["ke"] = max(out["ke"], float(ke.max()))
                out["held"] = int(across.sum())
                out["ke_held"] = max(out["ke_held"], float(ke[held].max(initial=0.0)))
    out["warned"] = None
    if any(issubclass(w.category, EnergyGrowthWarning) for w in caught):
        strand, frame = (int(v) for v in re.search(r"strand (\d+).* at frame (\d+)", monitor.message).groups())
        out["warned"] = (strand, frame, bool(near[max(frame - 1, 0):frame + 1, strand].any()), monitor.message)
    return out


def warning(warned):
    if warned is None:
        return ""
    strand, frame, near, _ = warned
    return f", energy warning (strand {strand}, frame {frame}, {'within' if near else 'beyond'} 1 mm of the shape)"


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--shapes", default="capsule1,capsule2,capsule3,sphere3,sphere5,plateX,plateY,plateZ")
    ap.add_argument("--speeds", default="0.5,1,2", help="m/s, comma separated")
    ap.add_argument("--segments", default="0.005,0.02", help="rest lengths (m), comma separated")
    ap.add_argument("--strands", type=int, default=5, help="strands per side of the square patch")
    ap.add_argument("--iterations", default="2", help="Colliders iterations, comma separated")
    ap.add_argument("--rest", type=int, default=24, help="frames the shape stands still after its 10 cm")
    ap.add_argument("--why", action="store_true", help="print the deepest first entries")
    ap.add_argument("--solver", default="dftl", help="dftl (default) or elastic (strands 100 um thick)")
    ap.add_argument("--split", type=int, default=None, help="print this strand's energy, split, after every frame")
    a = ap.parse_args()
    np.set_printoptions(precision=2, suppress=True)
    for iterations in (int(v) for v in a.iterations.split(",")):
        for segment in (float(v) for v in a.segments.split(",")):
            for name in a.shapes.split(","):
                for speed in (float(v) for v in a.speeds.split(",")):
                    o = run(name, speed, segment, a.strands, iterations, a.rest, solver_name=a.solver, split=a.split)
                    print(f"it {iterations} seg {segment * 1e3:4.1f} mm {name:9s} {speed:4.2f} m/s: deepest "
                          f"{o['worst'] * 1e3:5.3f} mm ({o['worst'] / RADIUS:4.1f} radii), first entries "
                          f"{len(o['entries']):2d}, moved {o['moved'] * 1e2:4.1f} cm, straddles {o['straddles']:4d} "
                          f"(most {o['most']:2d}, at rest {o['held']}), KE at rest {o['ke']:.1e} J/kg (straddling "
                          f"strands {o['ke_held']:.1e}){warning(o['warned'])}", flush=True)
                    if a.why and o["warned"]:
                        print(f"    {o['warned'][3]}")
                    for f, e, kinetic, gravity, elastic, turn in o.get("split", []):
                        print(f"    strand {a.split} frame {f}: energy {e:.3g} J/kg = kinetic {kinetic:.3g} + gravity "
                              f"{gravity:.3g} + elastic {elastic:.3g}; sharpest joint {turn:.0f} degrees")
                    for f, k, i, depth, q, lead, h in sorted(o["entries"], key=lambda e: -e[3])[:3] if a.why else []:
                        print(f"    frame {f} substep {k} strand {i // POINTS} point {i % POINTS}: {depth * 1e3:.3f} "
                              f"mm in at {q * 1e3} mm, leader {lead * 1e3}, leader's height above the contact "
                              f"plane {h * 1e3:.2f} mm (rest {segment * 1e3:g})")


if __name__ == "__main__":
    main()
