#!/usr/bin/env python3
"""Where the deforming body's per-frame update (``set_mesh_points``: refit, signed distance field)
spends its host time: the median host time of 20 updates of ``scripts/bench_features.py``'s
50,800-triangle body (and with the device synchronised), and a cProfile of them. ``old`` patches
back the axis-0 numpy bounds that ``dftl_warp/core/bounds.py`` replaced, for comparison.

    python scripts/profile_mesh_update.py cuda:0 100000 [old]
"""
import cProfile, pstats, sys, time
from pathlib import Path
sys.path.insert(0, str(Path(__file__).resolve().parent))
import numpy as np
import warp as wp
import bench_features as B

device = sys.argv[1] if len(sys.argv) > 1 else "cpu"
if len(sys.argv) > 3 and sys.argv[3] == "old":   # the code before core.bounds (axis-0 reductions)
    import dftl_warp.features.colliders.sdf as S
    import dftl_warp.features.colliders.mesh as MM
    def old_bounds(points):
        points = np.asarray(points).reshape(-1, 3)
        return points.min(0), points.max(0)
    def old_finite_rows(value, width, what):
        a = np.array(value, dtype=np.float64).reshape(-1, width)
        bad = ~np.isfinite(a).all(axis=1)
        if bad.any():
            raise ValueError(what)
        return a
    S.bounds = old_bounds
    MM.bounds = old_bounds
    MM.finite_rows = old_finite_rows
strands = int(sys.argv[2]) if len(sys.argv) > 2 else 1000
wp.config.quiet = True
wp.init()
pts, counts, roots = B.groom(strands)
rows = [r for r in B.scenarios(pts, counts, roots) if r[0].startswith("deforming body mesh") and "signed" in r[0]]
name, feats, extra = rows[0]
with wp.ScopedDevice(device):
    model, solver, state, control = B.build_scene(pts, counts, feats, extra, device)
    frames = extra["body_frames"]
    for f in range(3):
        control.features.set_mesh_points(0, frames[f % len(frames)])
    wp.synchronize_device(device)
    times = []
    pr = cProfile.Profile()
    for f in range(20):
        t = time.perf_counter()
        pr.enable()
        control.features.set_mesh_points(0, frames[f % len(frames)])
        pr.disable()
        t1 = time.perf_counter()
        wp.synchronize_device(device)
        times.append((t1 - t, time.perf_counter() - t))
    print("host call ms, with sync ms (median):", np.median([a for a, _ in times]) * 1e3,
          np.median([b for _, b in times]) * 1e3)
    pstats.Stats(pr).sort_stats("cumulative").print_stats(25)
