#!/usr/bin/env python3
"""Measurements behind the mesh colliders' signed distance field (docs/features.md, "Signed
distance fields of mesh colliders"):

- ``layouts``: per-frame build and per-sample cost of the field as bricks around the surface
  (what the collider uses), as a dense grid over the mesh's box, and sampled through Warp's
  volume API (NanoVDB, ``wp.volume_sample_grad_f``) -- on the bench's deforming head (50800
  triangles) and on a standing body 1.7 m tall (same triangle count, 4 and 2.5 mm cells);
- ``sign``: the sign of the nodes by the angle-weighted pseudo-normal
  (``wp.mesh_query_point_sign_normal``) against the winding number
  (``wp.mesh_query_point_sign_winding_number``): cost, and the nodes whose signs disagree, on the
  closed head and on an open sheet;
- ``triangles``: the cost per step of a groom of 200 strands settled on a bumpy sphere of 2k to
  51k triangles, through exact queries and through the field (static: built once), beside an
  analytic sphere, and the field's rebuild per frame.

    python scripts/bench_sdf.py --device cpu
"""

from __future__ import annotations

import argparse
import statistics
import time

import numpy as np
import warp as wp

import dftl_warp as dw
from dftl_warp import features as F
from dftl_warp.features.colliders.sdf import mesh_signed_distance
from dftl_warp.kernels.features import sdf as K
from bench_features import FPS, G, SUBSTEPS, body_mesh, body_points, groom, machine_line, uv_sphere


def timed(fn, device, repeats=3):
    fn()
    wp.synchronize_device(device)
    out = []
    for _ in range(repeats):
        t = time.perf_counter()
        fn()
        wp.synchronize_device(device)
        out.append(time.perf_counter() - t)
    return statistics.median(out)


@wp.kernel
def dense_sample_kernel(values: wp.array3d(dtype=wp.float32), origin: wp.vec3f, inv_cell: float,
                        points: wp.array(dtype=wp.vec3f), out: wp.array(dtype=wp.vec4f)):
    i = wp.tid()
    u = (points[i] - origin) * inv_cell
    fx = wp.floor(u[0])
    fy = wp.floor(u[1])
    fz = wp.floor(u[2])
    x = int(fx)
    y = int(fy)
    z = int(fz)
    tx = u[0] - fx
    ty = u[1] - fy
    tz = u[2] - fz
    c00 = (1.0 - tz) * values[x, y, z] + tz * values[x, y, z + 1]
    c01 = (1.0 - tz) * values[x, y + 1, z] + tz * values[x, y + 1, z + 1]
    c10 = (1.0 - tz) * values[x + 1, y, z] + tz * values[x + 1, y, z + 1]
    c11 = (1.0 - tz) * values[x + 1, y + 1, z] + tz * values[x + 1, y + 1, z + 1]
    c0 = (1.0 - ty) * c00 + ty * c01
    c1 = (1.0 - ty) * c10 + ty * c11
    gz = ((1.0 - tx) * ((1.0 - ty) * (values[x, y, z + 1] - values[x, y, z])
                        + ty * (values[x, y + 1, z + 1] - values[x, y + 1, z]))
          + tx * ((1.0 - ty) * (values[x + 1, y, z + 1] - values[x + 1, y, z])
                  + ty * (values[x + 1, y + 1, z + 1] - values[x + 1, y + 1, z])))
    g = wp.normalize(wp.vec3f(c1 - c0, (1.0 - tx) * (c01 - c00) + tx * (c11 - c10), gz))
    out[i] = wp.vec4f((1.0 - tx) * c0 + tx * c1, g[0], g[1], g[2])


@wp.kernel
def volume_sample_kernel(volume: wp.uint64, points: wp.array(dtype=wp.vec3f), out: wp.array(dtype=wp.vec4f)):
    i = wp.tid()
    uvw = wp.volume_world_to_index(volume, points[i])
    grad = wp.vec3f(0.0)
    d = wp.volume_sample_grad_f(volume, uvw, wp.Volume.LINEAR, grad)
    g = wp.normalize(grad)
    out[i] = wp.vec4f(d, g[0], g[1], g[2])


@wp.kernel
def brick_sample_kernel(grids: wp.array(dtype=K.SdfGrid), brick_map: wp.array(dtype=wp.int32),
                        values: wp.array(dtype=wp.float32), cells: wp.array(dtype=wp.uint8),
                        points: wp.array(dtype=wp.vec3f), out: wp.array(dtype=wp.vec4f)):
    i = wp.tid()
    s, d, n = K.sdf_sample(grids[0], brick_map, values, cells, points[i])
    out[i] = wp.vec4f(d, n[0], n[1], n[2])


@wp.kernel
def sign_kernel(mesh: wp.uint64, points: wp.array(dtype=wp.vec3f), max_dist: float, winding: int,
                sign: wp.array(dtype=wp.float32)):
    i = wp.tid()
    if winding == 1:
        q = wp.mesh_query_point_sign_winding_number(mesh, points[i], max_dist)
    else:
        q = wp.mesh_query_point_sign_normal(mesh, points[i], max_dist)
    sign[i] = 0.0
    if q.result:
        sign[i] = q.sign


def field_of(points, tris, device, cell=None):
    """A one-collider model's mesh fields (the collider's own build)."""
    model = dw.Model.from_strands(np.array([[0.0, 5.0, 0.0], [0.0, 5.01, 0.0]]), [2], widths=1e-4, device=device,
                                  features=[F.Colliders([F.TriangleMesh(points=points, indices=tris, sdf=True,
                                                                        sdf_cell=cell)])])
    control = model.control()
    meshes = control.features.colliders.kind_data["meshes"]
    return meshes, meshes.fields, meshes.meshes[0][1]


def standing_body(directions, t):
    """A 1.7 m standing body: the head's bumpy sphere stretched to 0.5 x 1.7 x 0.3 m."""
    return body_points(directions, t) / 0.095 * np.array([0.25, 0.85, 0.15])


def layouts(device, rows):
    dirs, tris = body_mesh()
    for label, pts, cell in (("deforming head (10 cm), 2.46 mm cells", body_points(dirs, 0.0), None),
                             ("standing body (1.7 m), 4 mm cells", standing_body(dirs, 0.0), 0.004),
                             ("standing body (1.7 m), 2.5 mm cells", standing_body(dirs, 0.0), 0.0025)):
        meshes, fields, mesh = field_of(pts, tris, device, cell)
        f = fields.fields[0]
        g = fields._grids_host[0]
        build = timed(lambda: fields.build(0, pts), device)
        nodes = f.used * K.BRICK_CELLS
        # the dense grid: every node of the bricks' box, queried as the bricks' nodes are
        dims = f.bricks * K.BRICK
        dense_nodes = int(np.prod(dims + 1))
        all_coords = wp.array(np.stack(np.meshgrid(*[np.arange(b) for b in f.bricks], indexing="ij"), -1)
                              .reshape(-1, 3).astype(np.int32), dtype=wp.vec3i, device=device)
        n_all = all_coords.shape[0]
        dense_values = wp.zeros(n_all * K.BRICK_NODES, dtype=wp.float32, device=device)
        dense_grads = wp.zeros(n_all * K.BRICK_NODES, dtype=wp.vec3h, device=device)
        g0 = K.SdfGrid()
        for name in ("origin", "cell", "inv_cell", "band", "reach", "tolerance", "bricks", "map_offset", "complete"):
            setattr(g0, name, getattr(g, name))
        g0.pool_offset = 0
        # the bricks' own nodes over every brick of the grid are the dense grid's nodes (but its last layer)
        dense_fill = timed(lambda: wp.launch(K.fill_nodes_kernel, dim=n_all * K.BRICK_CELLS, device=device,
                                             inputs=[mesh.id, g0, all_coords, dense_values, dense_grads]),
                           device, repeats=1) * dense_nodes / (n_all * K.BRICK_CELLS)
        rows.append(f"| {label}: bricks (used / reserved) | {f.used} / {f.capacity} bricks, {nodes} nodes queried, "
                    f"{fields.bytes / 2**20:.1f} MiB | build {build * 1e3:.1f} ms/frame |")
        rows.append(f"| {label}: dense grid over the box | {dense_nodes} nodes, {dense_nodes * 10 / 2**20:.1f} MiB "
                    f"(distance + gradient) | fill {dense_fill * 1e3:.1f} ms/frame |")
        if label.startswith("deforming head"):
            # sampling: 1M points within 5 mm of the surface
            rng = np.random.default_rng(0)
            idx = rng.integers(0, len(pts), 1_000_000)
            q = pts[idx] * (1.0 + rng.uniform(-0.05, 0.05, (len(idx), 1)))
            qd = wp.array(q.astype(np.float32), dtype=wp.vec3f, device=device)
            out = wp.zeros(len(idx), dtype=wp.vec4f, device=device)
            t_brick = timed(lambda: wp.launch(brick_sample_kernel, dim=len(idx), device=device,
                                              inputs=[fields.grids, fields.brick_map, fields.values, fields.cells,
                                                      qd, out]), device)
            # the same nodes as a dense array (from the bricks' values) and as a NanoVDB volume
            vals = dense_values.numpy().reshape(tuple(f.bricks) + (K.NODES,) * 3)
            dense = np.transpose(vals[..., :-1, :-1, :-1], (0, 3, 1, 4, 2, 5)).reshape(tuple(dims))
            dense_arr = wp.array(dense, dtype=wp.float32, device=device)
            t_dense = timed(lambda: wp.launch(dense_sample_kernel, dim=len(idx), device=device,
                                              inputs=[dense_arr, g.origin, g.inv_cell, qd, out]), device)
            volume = wp.Volume.load_from_numpy(dense, min_world=tuple(float(v) for v in g.origin),
                                               voxel_size=float(g.cell), bg_value=float(g.band), device=device)
            t_volume = timed(lambda: wp.launch(volume_sample_kernel, dim=len(idx), device=device,
                                               inputs=[volume.id, qd, out]), device)
            rows.append(f"| sample (distance + gradient), 1M points within 5 mm | bricks {t_brick * 1e3:.1f} ms, "
                        f"dense {t_dense * 1e3:.1f} ms | volume API {t_volume * 1e3:.1f} ms |")


def sign(device, rows):
    dirs, tris = body_mesh()
    pts = body_points(dirs, 0.0)
    rng = np.random.default_rng(1)
    idx = rng.integers(0, len(pts), 200_000)
    q = pts[idx] * (1.0 + rng.uniform(-0.08, 0.08, (len(idx), 1)))
    sheet_pts = np.array([[-1.0, 0.0, -1.0], [1.0, 0.0, -1.0], [1.0, 0.0, 1.0], [-1.0, 0.0, 1.0]]) * 0.2
    sheet_tris = np.array([[0, 2, 1], [0, 3, 2]])  # facing +y
    q_sheet = rng.uniform(-0.25, 0.25, (200_000, 3)) * np.array([1.0, 0.1, 1.0])
    for label, p, t, qq, truth in (("closed head", pts, tris, q, None),
                                   ("open sheet (inside behind its faces)", sheet_pts, sheet_tris, q_sheet,
                                    np.where(q_sheet[:, 1] < 0, -1.0, 1.0))):
        mesh = wp.Mesh(points=wp.array(p.astype(np.float32), dtype=wp.vec3, device=device),
                       indices=wp.array(t.reshape(-1).astype(np.int32), dtype=wp.int32, device=device),
                       support_winding_number=True)
        qd = wp.array(qq.astype(np.float32), dtype=wp.vec3f, device=device)
        out = {}
        for name, winding in (("normal", 0), ("winding", 1)):
            s = wp.zeros(len(qq), dtype=wp.float32, device=device)
            out[name] = (timed(lambda s=s, winding=winding: wp.launch(sign_kernel, dim=len(qq), device=device,
                                                                        inputs=[mesh.id, qd, 0.02, winding, s]), device),
                         np.sign(s.numpy()))
        found = out["normal"][1] != 0
        differ = int(np.count_nonzero(out["normal"][1][found] != out["winding"][1][found]))
        extra = ""
        if truth is not None:
            inside = np.abs(qq[:, 0]) < 0.2
            inside &= np.abs(qq[:, 2]) < 0.2
            keep = found & inside
            extra = (f"; over the sheet, wrong sign: normal {int(np.count_nonzero(out['normal'][1][keep] != truth[keep]))}, "
                     f"winding {int(np.count_nonzero(out['winding'][1][keep] != truth[keep]))} of {int(keep.sum())}")
        rows.append(f"| {label}: {int(found.sum())} points within 2 cm | normal {out['normal'][0] * 1e3:.1f} ms, "
                    f"winding {out['winding'][0] * 1e3:.1f} ms | signs differ at {differ}{extra} |")


def bumpy_sphere(rings, segments):
    dirs, tris = uv_sphere(1.0, rings, segments)
    y = np.clip(dirs[:, 1], -1, 1)
    theta, phi = np.arccos(y), np.arctan2(dirs[:, 2], dirs[:, 0])
    return dirs * (0.095 + 0.0025 * np.sin(5 * theta) * np.cos(4 * phi))[:, None], tris


def triangles(device, rows, strands=200):
    pts, counts, _ = groom(strands)
    dt = 1.0 / FPS / SUBSTEPS

    def step_time(feats):
        model = dw.Model.from_strands(pts, counts, widths=1e-4, device=device, features=feats)
        solver = dw.DFTLSolver(model, gravity=G, fused=False)
        state, control = solver.state(), model.control()
        for _ in range(12):
            solver.advance(state, control, dt, SUBSTEPS)
        return timed(lambda: solver.advance(state, control, dt, SUBSTEPS), device) / SUBSTEPS, control

    sphere, _ = step_time([F.Colliders([F.Sphere(radius=0.095)])])
    particle_steps = int(counts.sum())
    rows.append(f"| analytic sphere | - | {sphere / particle_steps * 1e9:.0f} ns | - | - | - | - |")
    for rings, segments in ((24, 48), (48, 96), (72, 140), (100, 200), (128, 200)):
        p, t = bumpy_sphere(rings, segments)
        exact, _ = step_time([F.Colliders([F.TriangleMesh(points=p, indices=t, sdf=False)])])
        field, control = step_time([F.Colliders([F.TriangleMesh(points=p, indices=t, sdf=True)])])
        meshes = control.features.colliders.kind_data["meshes"]
        rebuild = timed(lambda: meshes.set_points(0, p), device)
        stats = meshes.fields.stats(0)
        # the field against the exact distance at 100k points within 2 mm of the surface
        rng = np.random.default_rng(2)
        q = p[rng.integers(0, len(p), 100_000)]
        q = q + rng.uniform(-0.002, 0.002, q.shape)
        state, d, _ = meshes.fields.sample(0, q)
        exact_d, _ = mesh_signed_distance(meshes.meshes[0][1], q)
        answered = state == 1
        error = float(np.abs(d[answered] - exact_d[answered]).max())
        rows.append(f"| {len(t)} triangles | {stats['cell'] * 1e3:.2f} mm | {exact / particle_steps * 1e9:.0f} ns | "
                    f"{field / particle_steps * 1e9:.0f} ns | {rebuild * 1e3:.0f} ms | "
                    f"{answered.mean():.4f} | {error * 1e6:.0f} um ({stats['tolerance'] * 1e6:.0f} um) |")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--device", default="cpu")
    ap.add_argument("--only", choices=("layouts", "sign", "triangles"), default=None)
    args = ap.parse_args(argv)
    wp.config.quiet = True
    wp.init()
    device = wp.get_device(args.device)
    print(f"{machine_line(device)}, {time.strftime('%Y-%m-%d %H:%M', time.gmtime())} UTC\n")
    with wp.ScopedDevice(device):
        if args.only in (None, "layouts"):
            rows = ["| field layout | size | cost |", "|---|---|---|"]
            layouts(device, rows)
            print("\n".join(rows) + "\n")
        if args.only in (None, "sign"):
            rows = ["| sign of the distance | cost | agreement |", "|---|---|---|"]
            sign(device, rows)
            print("\n".join(rows) + "\n")
        if args.only in (None, "triangles"):
            rows = ["| bumpy sphere (9.5 cm) | default cell | step per particle-step, exact queries | "
                    "step per particle-step, field | field rebuild per frame | points within 2 mm answered "
                    "by the field | largest error there (tolerance) |", "|---|---:|---:|---:|---:|---:|---:|"]
            triangles(device, rows)
            print("\n".join(rows) + "\n")


if __name__ == "__main__":
    main()
