#!/usr/bin/env python3
"""Per-step cost of each optional feature on its own, against the bare DFTL step.

The scene: a head-sized groom (roots on the upper half of a 10 cm sphere, strands of 32 vertices
combed outward and down), stepped a frame of 10 substeps at a time (a CUDA graph on the GPU),
timed after 12 frames (0.5 s) in which it falls onto the head and settles. The colliders
stand for the head (sphere, mesh) or sit below it (capsule: a neck, box: shoulders). The
deforming body (a bumpy closed head of 50800 triangles whose points change every frame, as a point
cache's) runs twice: through exact mesh queries and through its signed distance field; its rows
include the per-frame update (BVH refit, and the field's rebuild), which is also given on its own.
Each row runs the same groom with one feature; the last rows run the production scene of issue 20
(the deforming body through its field, hair-hair, wind with curl noise and drag) with DFTL strands
and with elastic strands (``ELASTIC``: 100 um hair, float32 arithmetic), beside the elastic strands
with gravity only. The ratio is to the bare step timed in the same run. On CUDA the bare rows use the per-substep kernel (``fused=False``), the
path features take; the fused-substep figure is given for reference. ``--only NAME ...`` runs the
rows whose names start with one of these (and the bare row), without the collision measures.

    python scripts/bench_features.py --device cpu --out docs/bench/features-cpu
    python scripts/bench_features.py --device cuda:0 --out $OUT

:func:`run` returns the markdown table rows; ``--out`` also gets ``features-<device>.md`` and
``features-<device>.json``.
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import platform
import statistics
import sys
import time
from pathlib import Path

import numpy as np
import warp as wp


import dftl_warp as dw  # noqa: E402
from dftl_warp import features as F  # noqa: E402
import dftl_warp.features.step as feature_step  # noqa: E402
from dftl_warp.kernels.features import sdf as sdf_kernels  # noqa: E402
from dftl_warp.core.layout import strand_offsets  # noqa: E402
from dftl_warp.features.colliders.mesh import MeshColliders  # noqa: E402
from dftl_warp.features.colliders.sdf import mesh_signed_distance  # noqa: E402

G = (0.0, -9.81, 0.0)
FPS = 24
SUBSTEPS = 10
#: frames run before timing: the groom falls onto the head and settles
SETTLE_FRAMES = 12
HEAD = 0.1  # m


def uv_sphere(radius, rings=24, segments=48):
    """Closed UV sphere mesh with outward-facing triangles: points (P, 3), indices (T, 3)."""
    theta = np.linspace(0, np.pi, rings + 1)[1:-1]
    phi = np.linspace(0, 2 * np.pi, segments, endpoint=False)
    t, p = np.meshgrid(theta, phi, indexing="ij")
    ring_pts = np.stack([np.sin(t) * np.cos(p), np.cos(t), np.sin(t) * np.sin(p)], -1).reshape(-1, 3)
    pts = np.concatenate([[[0, 1, 0]], ring_pts, [[0, -1, 0]]]) * radius
    tris = []
    ring = lambda r, s: 1 + r * segments + s % segments  # noqa: E731
    for s in range(segments):
        tris.append((0, ring(0, s + 1), ring(0, s)))
        last = len(pts) - 1
        tris.append((last, ring(rings - 2, s), ring(rings - 2, s + 1)))
        for r in range(rings - 2):
            a, b, c, d = ring(r, s), ring(r, s + 1), ring(r + 1, s), ring(r + 1, s + 1)
            tris += [(a, b, d), (a, d, c)]
    tris = np.array(tris)
    tri = pts[tris]
    normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    flip = np.sum(normal * tri.mean(1), axis=1) < 0
    tris[flip] = tris[flip][:, ::-1]
    return pts, tris


#: the deforming body: a bumpy closed head of BODY_RINGS x BODY_SEGMENTS (50800 triangles), under the
#: groom's roots (its surface stays below 9.9 cm; the roots sit at 10.2 cm)
BODY_RINGS, BODY_SEGMENTS = 128, 200
#: the body's deformation repeats every BODY_PERIOD seconds (its frames are computed once)
BODY_PERIOD = 2.0


def body_mesh(rings=BODY_RINGS, segments=BODY_SEGMENTS):
    """A closed body-like mesh: unit directions (P, 3) of a UV sphere and its triangles (T, 3);
    :func:`body_points` places the points at a time."""
    return uv_sphere(1.0, rings, segments)


def body_points(directions, t):
    """Points (P, 3), m, of the deforming body at time ``t`` (s): a 9.5 cm sphere breathing by
    +-1.5 mm (period 2 s) with +-2.5 mm bumps travelling around it (0.5 Hz)."""
    y = np.clip(directions[:, 1], -1.0, 1.0)
    theta = np.arccos(y)
    phi = np.arctan2(directions[:, 2], directions[:, 0])
    w = 2.0 * np.pi / BODY_PERIOD
    r = 0.095 + 0.0015 * np.sin(w * t) + 0.0025 * np.sin(5.0 * theta) * np.cos(4.0 * phi - w * t)
    return directions * r[:, None]


def body_frames(directions, frames):
    """The body's points at each of ``frames`` frames of one period (cycled by the runs)."""
    return [body_points(directions, f / FPS) for f in range(frames)]


def groom(num_strands, count=32, seed=0):
    """Strands rooted on the upper half of the head sphere, combed outward then down."""
    rng = np.random.default_rng(seed)
    d = rng.normal(size=(num_strands, 3))
    d[:, 1] = np.abs(d[:, 1])
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    roots = d * (HEAD + 0.002)
    seg = 0.01
    out = d + np.array([0.0, -0.5, 0.0])
    out /= np.linalg.norm(out, axis=1, keepdims=True)
    pts = roots[:, None] + np.arange(count)[None, :, None] * seg * out[:, None]
    return pts.reshape(-1, 3), np.full(num_strands, count), roots


def patch(pts, counts, roots, size: int):
    """The ``size`` strands of a :func:`groom` rooted nearest one point on the crown's side: a patch
    as dense as the whole groom, small enough for the CPU. Returns ``(pts, counts, roots)``."""
    centre = np.array([0.6, 0.6, 0.53]) * np.linalg.norm(roots[0])
    keep = np.sort(np.argsort(np.linalg.norm(roots - centre, axis=1))[:size])
    n = int(counts[0])
    return pts.reshape(len(counts), n, 3)[keep].reshape(-1, 3), counts[keep], roots[keep]


def patched_groom(num_strands, size=None):
    """``(pts, counts, roots)`` of :func:`groom`, or of its :func:`patch` of ``size`` strands."""
    pts, counts, roots = groom(num_strands)
    return patch(pts, counts, roots, size) if size else (pts, counts, roots)


def scenarios(pts, counts, roots):
    mesh_pts, mesh_tris = uv_sphere(HEAD)
    n = len(counts)
    bind_tris = np.array([[0, 1, 2]])
    dirs, body_tris = body_mesh()
    frames = body_frames(dirs, int(round(BODY_PERIOD * FPS)))
    deform = dict(body_frames=frames)
    return [
        ("bare DFTL step", None, {}),
        ("gravity-only scene (features=[])", [], {}),
        ("root binding (per frame only)", [F.RootBinding(np.array([[0, 0, 0], [1, 0, 0], [0, 0, 1.0]]), bind_tris,
                                                          triangles=np.zeros(n, int),
                                                          weights=np.tile([1.0, 0, 0], (n, 1)))], {}),
        ("sphere collider", [F.Colliders([F.Sphere(radius=HEAD)])], {}),
        ("capsule collider", [F.Colliders([F.Capsule(radius=0.05, half_height=0.1, axis="Y",
                                                     position=(0, -0.2, 0))])], {}),
        ("box collider", [F.Colliders([F.Box(half_extents=(0.15, 0.1, 0.1), position=(0, -0.35, 0))])], {}),
        (f"mesh collider ({len(mesh_tris)} triangles)",
         [F.Colliders([F.TriangleMesh(points=mesh_pts, indices=mesh_tris)])], {}),
        (f"deforming body mesh ({len(body_tris)} triangles), exact queries",
         [F.Colliders([F.TriangleMesh(points=frames[0], indices=body_tris, sdf=False)])], deform),
        (f"deforming body mesh ({len(body_tris)} triangles), signed distance field",
         [F.Colliders([F.TriangleMesh(points=frames[0], indices=body_tris, sdf=True)])], deform),
        ("drag", [F.Drag(1.0)], {}),
        ("wind + drag", [F.Drag(1.0), F.Wind(velocity=(1.0, 0.0, 0.0))], {}),
        ("wind with curl noise + drag", [F.Drag(1.0), F.Wind(velocity=(1.0, 0, 0), noise_amplitude=0.5)], {}),
        ("hair-hair grid (1 cm cells)", [F.HairHair(cell_size=0.01)], {}),
        # the production scene of issue 20, with DFTL strands, then with elastic strands
        (f"production scene: deforming body ({len(body_tris)} triangles, field) + hair-hair + wind with curl "
         "noise + drag", [F.Colliders([F.TriangleMesh(points=frames[0], indices=body_tris, sdf=True)]),
                          F.HairHair(cell_size=0.01), F.Drag(1.0),
                          F.Wind(velocity=(1.0, 0, 0), noise_amplitude=0.5)], deform),
        ("production scene, hair-hair threshold 0 (all the density pushes; the default: the densest node at rest)",
         [F.Colliders([F.TriangleMesh(points=frames[0], indices=body_tris, sdf=True)]),
          F.HairHair(cell_size=0.01, threshold=0.0), F.Drag(1.0),
          F.Wind(velocity=(1.0, 0, 0), noise_amplitude=0.5)], deform),
        ("production scene, hair-hair grid rebuilt every 5 substeps (splat_interval=5)",
         [F.Colliders([F.TriangleMesh(points=frames[0], indices=body_tris, sdf=True)]),
          F.HairHair(cell_size=0.01, splat_interval=5), F.Drag(1.0),
          F.Wind(velocity=(1.0, 0, 0), noise_amplitude=0.5)], deform),
        ("elastic strands, gravity only (float32 arithmetic)", [], dict(ELASTIC)),
        (f"production scene with elastic strands (float32 arithmetic): deforming body ({len(body_tris)} triangles, "
         "field) + hair-hair + wind with curl noise + drag",
         [F.Colliders([F.TriangleMesh(points=frames[0], indices=body_tris, sdf=True)]),
          F.HairHair(cell_size=0.01), F.Drag(1.0), F.Wind(velocity=(1.0, 0, 0), noise_amplitude=0.5)],
         dict(deform, **ELASTIC)),
        ("production scene with elastic strands, hair-hair threshold 0",
         [F.Colliders([F.TriangleMesh(points=frames[0], indices=body_tris, sdf=True)]),
          F.HairHair(cell_size=0.01, threshold=0.0), F.Drag(1.0), F.Wind(velocity=(1.0, 0, 0), noise_amplitude=0.5)],
         dict(deform, **ELASTIC)),
    ]


#: the elastic rows' solver: the elastic rod solver (the groom's widths: 100 um hair), float32 arithmetic
ELASTIC = dict(solver="elastic", solver_options=dict(compute_precision="float32"))


def build_scene(pts, counts, feats, extra, device):
    """(model, solver, state, control) of one row: the groom with ``feats``, its solver from
    ``extra`` (DFTL substep by substep unless ``extra["solver"]`` names another)."""
    model = dw.Model.from_strands(pts, counts, device=device, widths=1e-4, features=feats)
    if extra.get("solver", "dftl") == "dftl":
        solver = dw.DFTLSolver(model, gravity=G, fused=False)
    else:
        solver = dw.make_solver(model, extra["solver"], gravity=G, **extra.get("solver_options", {}))
    return model, solver, solver.state(), model.control()


def timed(fn, device, repeats):
    """Seconds of each of ``repeats`` calls of ``fn`` (device synchronised)."""
    wp.synchronize_device(device)
    times = []
    for _ in range(repeats):
        t = time.perf_counter()
        fn()
        wp.synchronize_device(device)
        times.append(time.perf_counter() - t)
    return times


def time_frames(fn, device, repeats):
    """Median seconds of ``fn`` after one warm-up call (compiles, captures)."""
    fn()
    return statistics.median(timed(fn, device, repeats))


def box_mesh(half):
    """Closed box mesh of half extents ``half`` (8 points, 12 outward triangles)."""
    hx, hy, hz = half
    p = np.array([[x, y, z] for x in (-hx, hx) for y in (-hy, hy) for z in (-hz, hz)])
    quads = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    return p, np.array([t for a, b, c, d in quads for t in ((a, b, c), (a, c, d))])


def segment_stretch(x, counts, rest):
    starts = strand_offsets(counts)
    d = np.linalg.norm(np.diff(x, axis=0), axis=1)
    keep = np.ones(len(d), dtype=bool)
    keep[starts[1:] - 1] = False
    return np.abs(d[keep] / rest - 1).max()


def collision_guarantees(device="cpu", precision="float32"):
    """Worst penetration and stretch over every substep of the acceptance scenes (as in
    tests/test_features.py): strands draped on a sphere, ploughed by a capsule at 1 m/s (10
    substeps at 24 fps); a strand falling at 10 m/s onto a 2 cm mesh slab (1 substep at 24 fps)."""
    out = {}
    sphere_r, cap_r, cap_half, width, n = 0.1, 0.03, 0.1, 0.002, 40
    pts = np.concatenate([np.stack([np.full(n, x), np.full(n, sphere_r + 0.005), np.arange(n) * 0.01 - 0.02], 1)
                          for x in np.linspace(-0.04, 0.04, 9)])
    counts = np.full(9, n)
    start = np.array([0.3, -0.17, 0.11])
    centre = lambda t: start + np.array([-1.0, 0.0, 0.0]) * max(t - 1.0, 0.0)  # noqa: E731
    cols = F.Colliders([F.Sphere(radius=sphere_r), F.Capsule(radius=cap_r, half_height=cap_half, axis="Z",
                                                               position=start)])
    with wp.ScopedDevice(device):
        model = dw.Model.from_strands(pts, counts, widths=width, features=[cols], device=device, precision=precision)
        solver = dw.DFTLSolver(model, gravity=G)
        state, control = solver.state(), model.control()
        worst_s = worst_c = stretch = 0.0
        for f in range(60):
            ident = [0, 0, 0, 0, 0, 0, 1]
            control.features.set_collider_poses([ident, [*centre(f / FPS), 0, 0, 0, 1]],
                                                [ident, [*centre((f + 1) / FPS), 0, 0, 0, 1]])
            for k in range(SUBSTEPS):
                solver.step(state, state, control, 1 / FPS / SUBSTEPS, (k + 1) / SUBSTEPS)
                x = model.points_from_device(state.positions)
                q = x - centre((f + (k + 1) / SUBSTEPS) / FPS)
                axial = np.clip(q[:, 2], -cap_half, cap_half)
                dc = np.linalg.norm(q - axial[:, None] * [0, 0, 1], axis=1)
                worst_s = max(worst_s, (sphere_r + width / 2 - np.linalg.norm(x, axis=1)).max())
                worst_c = max(worst_c, (cap_r + width / 2 - dc).max())
                stretch = max(stretch, segment_stretch(x, counts, 0.01))
        out["sphere penetration / radius"] = max(worst_s, 0.0) / sphere_r
        out["moving capsule penetration / radius"] = max(worst_c, 0.0) / cap_r
        out["drape stretch"] = stretch
        points, tris = box_mesh((1.0, 0.01, 1.0))
        n = 20
        pts = np.stack([np.linspace(-0.3, 0.3, n), np.full(n, 0.3), np.zeros(n)], 1)
        model = dw.Model.from_strands(pts, [n], widths=width, device=device, precision=precision,
                                      features=[F.Colliders([F.TriangleMesh(points=points, indices=tris)])])
        solver = dw.DFTLSolver(model, gravity=G)
        state, control = solver.state(), model.control()
        v = np.zeros_like(pts)
        v[1:, 1] = -10.0
        state.write("velocities", model.points_to_device(v, relative=False), layout=model.layout)
        lowest, stretch = np.inf, 0.0
        for _ in range(FPS):
            solver.step(state, state, control, 1 / FPS)
            x = model.points_from_device(state.positions)
            lowest = min(lowest, x[:, 1].min())
            stretch = max(stretch, segment_stretch(x, [n], np.linalg.norm(pts[1] - pts[0])))
        out["slab penetration (10 m/s, 1 substep) / hair radius"] = max(0.01 + width / 2 - lowest, 0.0) / (width / 2)
        out["slab stretch"] = stretch
    return out


def body_penetration(device="cpu", precision="float32", strands=64, frames=24):
    """Worst penetration of the contact distance (hair radii) over every substep of a groom of
    ``strands`` falling onto the deforming body (its points set per frame), with exact mesh
    queries and with the signed distance field, with the default 2 collision rounds and with 4,
    measured against the body's own mesh (exact signed distance, the mesh as the step sees it);
    and the field's statistics at the end."""
    pts, counts, _ = groom(strands)
    dirs, tris = body_mesh()
    cycle = body_frames(dirs, int(round(BODY_PERIOD * FPS)))
    width = 1e-4
    out = {}
    with wp.ScopedDevice(device):
        for label, sdf, rounds in (("exact queries", False, 2), ("exact queries, 4 collision rounds", False, 4),
                                   ("signed distance field", True, 2),
                                   ("signed distance field, 4 collision rounds", True, 4)):
            feats = [F.Colliders([F.TriangleMesh(points=cycle[0], indices=tris, sdf=sdf)], iterations=rounds)]
            model = dw.Model.from_strands(pts, counts, widths=width, features=feats, device=device, precision=precision)
            solver = dw.DFTLSolver(model, gravity=G)
            state, control = solver.state(), model.control()
            meshes = control.features.colliders.kind_data["meshes"]
            worst = 0.0
            for f in range(frames):
                control.features.set_mesh_points(0, cycle[(f + 1) % len(cycle)])
                for k in range(SUBSTEPS):
                    solver.step(state, state, control, 1 / FPS / SUBSTEPS, (k + 1) / SUBSTEPS)
                    x = model.points_from_device(state.positions)
                    d, _ = mesh_signed_distance(meshes.mesh_now(0), x, max_dist=0.05)
                    worst = max(worst, float((width / 2 - d).max()))
            out[f"deforming body ({len(tris)} triangles), {label}: penetration / hair radius"] = worst / (width / 2)
            if sdf and rounds == 2:
                stats = meshes.fields.stats(0)
    out["deforming body: field cell (mm)"] = 1e3 * stats["cell"]
    out["deforming body: field tolerance (mm)"] = 1e3 * stats["tolerance"]
    out["deforming body: band cells answered by the field (end)"] = stats["answering_fraction"]
    return out


def machine_line(device):
    d = wp.get_device(device)
    if d.is_cuda:
        return f"{d.name}, Warp {wp.__version__}"
    cpu = platform.processor() or platform.machine()
    try:
        for line in open("/proc/cpuinfo"):
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return f"{cpu}, {os.cpu_count()} cores, Warp {wp.__version__} (CPU backend)"


def run(device="cpu", out_dir=None, strands=None, repeats=None, only=None):
    """Time every scenario on ``device`` (``only``: those whose names start with one of these
    strings, and the bare row); return the markdown rows (header first)."""
    wp.config.quiet = True
    wp.config.log_level = wp.LOG_WARNING
    wp.init()
    device = wp.get_device(device)
    strands = strands or (100_000 if device.is_cuda else 1_000)
    repeats = repeats or (20 if device.is_cuda else 15)
    pts, counts, roots = groom(strands)
    particles = int(counts.sum())
    dt = 1.0 / FPS / SUBSTEPS
    runs = []
    updates = {}
    rows = scenarios(pts, counts, roots)
    if only:
        rows = rows[:1] + [r for r in rows[1:] if r[0].startswith(tuple(only))]
    for name, feats, extra in rows:
        started = time.perf_counter()
        with wp.ScopedDevice(device):
            model, solver, state, control = build_scene(pts, counts, feats, extra, device)
            binding = model.feature_data is not None and model.feature_data.binding is not None
            frames = extra.get("body_frames")
            if frames is not None:
                updates[name] = []

            def one_frame(solver=solver, state=state, control=control, binding=binding, frames=frames,
                          clock=[0], spent=updates.get(name)):
                if binding:
                    control.bind_roots(np.array([[0, 0, 0], [1, 0, 0], [0, 0, 1.0]]))
                if frames is not None:  # the body's points at the frame's end: refit (and field) per frame
                    clock[0] += 1
                    t = time.perf_counter()
                    control.features.set_mesh_points(0, frames[clock[0] % len(frames)])
                    wp.synchronize_device(device)
                    spent.append(time.perf_counter() - t)
                solver.advance(state, control, dt, SUBSTEPS)

            for _ in range(SETTLE_FRAMES):  # warm-up (compile, capture), and let the groom settle
                one_frame()
            print(f"{name}: set up, compiled and settled in {time.perf_counter() - started:.1f} s", flush=True)
            if frames is not None:
                del updates[name][:]
            runs.append((name, model, solver, state, control, one_frame, []))
    # rounds over all scenarios, so that load from elsewhere spreads evenly over them
    for _ in range(repeats):
        for *_, one_frame, times in runs:
            wp.synchronize_device(device)
            t = time.perf_counter()
            one_frame()
            wp.synchronize_device(device)
            times.append(time.perf_counter() - t)
    results = []
    bare = None
    for name, model, solver, state, control, _, times in runs:
        seconds = statistics.median(times) / SUBSTEPS
        if bare is None:
            bare = seconds
        results.append(dict(scenario=name, flags=sorted(model.feature_flags), seconds_per_step=seconds,
                            particle_steps_per_s=particles / seconds, vs_bare=seconds / bare,
                            max_stretch=solver.diagnostics(state)["max_stretch"]))
        if name in updates:
            results[-1]["mesh_update_per_frame_s"] = statistics.median(updates[name])
            meshes = control.features.colliders.kind_data["meshes"]
            if meshes.fields.fields:
                results[-1]["field"] = meshes.fields.stats(int(model.feature_data.collider_order[0]))
    if device.is_cuda:
        with wp.ScopedDevice(device):
            model = dw.Model.from_strands(pts, counts, device=device)
            solver = dw.DFTLSolver(model, gravity=G, fused=True)
            state, control = solver.state(), model.control()
            seconds = time_frames(lambda: solver.advance(state, control, dt, SUBSTEPS), device, repeats) / SUBSTEPS
        results.append(dict(scenario="bare, fused substeps (reference)", flags=[], seconds_per_step=seconds,
                            particle_steps_per_s=particles / seconds, vs_bare=seconds / bare, max_stretch=0.0))

    guarantees = {}
    if not only:  # the collision measures come with the whole table
        guarantees = collision_guarantees(device)
        guarantees.update(body_penetration(device))
    rows = ["| scenario | kernel flags | time per step | particle-steps/s | vs bare |",
            "|---|---|---:|---:|---:|"]
    for r in results:
        flags = ", ".join(r["flags"]) or "(none: bare kernel)"
        rows.append(f"| {r['scenario']} | {flags} | {r['seconds_per_step'] * 1e3:.3f} ms | "
                    f"{r['particle_steps_per_s']:.3g} | {r['vs_bare']:.2f}x |")
    if guarantees:
        rows += ["", "| collision measure (worst over every substep) | value |", "|---|---:|"]
        rows += [f"| {k} | {v:.3g} |" for k, v in guarantees.items()]
    deforming = [r for r in results if "mesh_update_per_frame_s" in r]
    if deforming:
        rows += ["", "| deforming body: per-frame mesh update (set_mesh_points: refit, field) | time per frame | "
                     "field bricks used / reserved | band cells answered by the field |", "|---|---:|---:|---:|"]
        for r in deforming:
            field = r.get("field")
            bricks = f"{field['bricks_used']} / {field['bricks_reserved']}" if field else "-"
            answered = f"{field['answering_fraction']:.4f}" if field else "-"
            rows.append(f"| {r['scenario']} | {r['mesh_update_per_frame_s'] * 1e3:.3f} ms | {bricks} | {answered} |")
    if out_dir is not None:
        out = Path(out_dir)
        out.mkdir(parents=True, exist_ok=True)
        tag = device.alias.replace(":", "")
        header = (f"Feature costs on {machine_line(device)}; {strands} strands x 32 vertices "
                  f"({particles} particles), float32, prior correction, dt = 1/{FPS * SUBSTEPS} s, "
                  f"median of {repeats} frames of {SUBSTEPS} substeps after {SETTLE_FRAMES} settling frames (rounds over all scenarios); "
                  f"{datetime.datetime.now(datetime.timezone.utc):%Y-%m-%d %H:%M} UTC; hair-hair, drag and wind "
                  f"{'in their own pass before the sweep' if feature_step.VELOCITY_PASS else 'in the sweep'}; "
                  f"the field's trace: path bounds {sdf_kernels.PATH_BOUNDS}, relaxation {sdf_kernels.RELAXATION}, "
                  f"{sdf_kernels.FIELD_TRACE_ITERATIONS} steps.\n\n")
        (out / f"features-{tag}.md").write_text(header + "\n".join(rows) + "\n")
        (out / f"features-{tag}.json").write_text(json.dumps(
            dict(device=machine_line(device), strands=strands, particles=particles, results=results,
                 collision=guarantees), indent=2))
    return rows


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--device", default="cpu")
    ap.add_argument("--out", default=None, help="folder for features-<device>.md and .json")
    ap.add_argument("--strands", type=int, default=None, help="groom size (default 1k on CPU, 100k on CUDA)")
    ap.add_argument("--repeats", type=int, default=None)
    ap.add_argument("--only", nargs="*", default=None, help="run only the rows whose names start with one of these")
    ap.add_argument("--no-velocity-pass", action="store_true",
                    help="hair-hair, drag and wind in the sweep, as before their own pass "
                         "(dftl_warp/features/step.py: VELOCITY_PASS)")
    ap.add_argument("--plain-field-trace", action="store_true",
                    help="the field's continuous test as before its path bounds and relaxed steps (16 plain steps; "
                         "kernels/features/sdf.py: PATH_BOUNDS, RELAXATION, FIELD_TRACE_ITERATIONS)")
    ap.add_argument("--mesh-two-refits", action="store_true",
                    help="a deforming mesh's two meshes written and refitted every substep, as before the "
                         "ping-pong (dftl_warp/features/colliders/mesh.py: MeshColliders._ping_pong; the "
                         "exact-queries row's per-frame update then holds a refit that the ping-pong does "
                         "in the frame's first substep: compare the rows' times per step)")
    args = ap.parse_args(argv)
    if args.mesh_two_refits:
        MeshColliders._ping_pong = False
    if args.no_velocity_pass:
        feature_step.VELOCITY_PASS = False
    if args.plain_field_trace:  # before any kernel is built
        sdf_kernels.PATH_BOUNDS, sdf_kernels.RELAXATION, sdf_kernels.FIELD_TRACE_ITERATIONS = 0, 1.0, 16
    print("\n".join(run(args.device, args.out, args.strands, args.repeats, args.only)))


if __name__ == "__main__":
    main()
