#!/usr/bin/env python3
"""What the production scene's DFTL sweep pays for: its kernel time (CUDA activity timing, as
``profile_features.py``) with parts of the mesh collider's code patched out before any kernel is
built, one variant per process (the kernels are cached per process).

Variants (any combination of the words, e.g. ``noexact_notrace``): ``default``; ``noexact``: the
exact mesh query where the field cannot answer replaced by "no contact"; ``exactdead``: its code
kept but never run (a runtime condition the compiler cannot drop: what the code's registers cost
without its work); ``notrace``: no trace through the field (traced paths go to the exact query);
``iter1``: one collision round instead of two. A diagnostic: the patched variants do not collide
correctly. Writes ``probe-VARIANT-STRANDS.json`` (ms per step per kernel) to OUT.

    for v in default noexact exactdead noexact_notrace; do
        python scripts/probe_sweep_variants.py $v 1000000 $OUT; done
"""
import sys, json, time
from pathlib import Path
sys.path.insert(0, str(Path(__file__).resolve().parent))
import numpy as np
import warp as wp
variant, strands, out = sys.argv[1], int(sys.argv[2]), sys.argv[3]
from dftl_warp.kernels.features import sdf as sdf_k, mesh as mesh_k
import dftl_warp.features as F
if "noexact" in variant:
    def fake(scalar):
        vec3 = wp.types.vector(3, scalar)
        tr = wp.types.transformation(dtype=scalar)
        def collide_mesh(x: vec3, x_old: vec3, leader: vec3, rest: scalar, ccd: bool, radius: scalar, pose: tr,
                         inv_pose: tr, inv_pose_prev: tr, mesh: wp.uint64, mesh_prev: wp.uint64, motion: scalar,
                         lower: vec3, upper: vec3,
                         depth_band: scalar, mu: scalar):
            return x, False
        collide_mesh.__name__ = collide_mesh.__qualname__ = "fake_mesh_" + str(scalar.__name__)
        return wp.func(collide_mesh)
    mesh_k.collide_mesh_func = fake
if "exactdead" in variant:
    import functools
    from dftl_warp.kernels.features.collide import named_func
    @functools.cache
    def built(scalar, Features, count):
        vec3 = wp.types.vector(3, scalar)
        one = mesh_k.collide_mesh_func(scalar)
        field = sdf_k.collide_sdf_func(scalar)
        def collide_mesh_at(f: Features, c: int, x: vec3, x_old: vec3, leader: vec3, rest: scalar, ccd: bool,
                            radius: scalar):
            grid = f.collider_sdf[c]
            if grid.cell > wp.float32(0.0):
                z, touched, why, taken = field(x, x_old, leader, rest, ccd, radius, f.collider_pose[c],
                                               f.collider_inv_pose[c], f.collider_inv_pose_prev[c], grid,
                                               f.sdf_brick_map, f.sdf_values, f.sdf_cells, f.collider_depth_band[c],
                                               f.collider_friction[c])
                if why < sdf_k.EXACT_FROM or f.collider_friction[c] > scalar(-1.0):
                    return z, touched
            y, hit = one(x, x_old, leader, rest, ccd, radius, f.collider_pose[c], f.collider_inv_pose[c],
                         f.collider_inv_pose_prev[c], f.collider_mesh[c], f.collider_mesh_prev[c],
                         f.collider_motion[c], f.collider_lower[c], f.collider_upper[c],
                         f.collider_depth_band[c], f.collider_friction[c])
            return y, hit
        return named_func(collide_mesh_at, "collide_mesh_at_dead", unique=True)
    mesh_k._collide_mesh_at_built = built
if "notrace" in variant:
    sdf_k.FIELD_TRACE_ITERATIONS = 0
import profile_features as pf
from bench_features import groom, scenarios
wp.config.quiet = True
wp.init()
import os; dev = wp.get_device(os.environ.get("PROBE_DEVICE", "cuda:0"))
pts, counts, roots = groom(strands)
rows = [r for r in scenarios(pts, counts, roots) if r[0].startswith(("bare DFTL", "production scene:"))]
res = {}
for name, feats, extra in rows:
    if "iter1" in variant and feats:
        feats = [F.Colliders(f.shapes, iterations=1) if isinstance(f, F.Colliders) else f for f in feats]
    with wp.ScopedDevice(dev):
        one = pf.build(pts, counts, feats, extra, dev)
        kernels, wall = pf.profile(one, dev, 3) if dev.is_cuda else (one(graph=False) or {}, 0)
    res[name] = {k: s * 1e3 for k, (n, s) in kernels.items()}
    print(variant, name[:30], {k[:40]: round(v, 3) for k, v in res[name].items()}, flush=True)
Path(out).mkdir(parents=True, exist_ok=True)
(Path(out) / f"probe-{variant}-{strands}.json").write_text(json.dumps(res, indent=1))
