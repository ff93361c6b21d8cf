"""Guides driving render strands (issue 22): time and memory of the deformation, and guide selection
measured against simulating every strand.

Timing (synthetic groom on a sphere of radius 0.1 m: straight-ish guides, curly render strands):

    .venv/bin/python scripts/bench_guides.py --device cuda:0 --guides 10000 --render 1000000 --vertices 32 --out DIR
    .venv/bin/python scripts/bench_guides.py --device cpu --guides 100 --render 2000 --out DIR

Selection (a real groom, e.g. the TressFX Ratboy mohawk; every strand simulated vs guides only):

    .venv/bin/python scripts/bench_guides.py --selection Ratboy_mohawk.tfx --fractions 0.05 0.1 0.2 --out DIR

Prints a markdown table and writes ``DIR/bench_guides.json`` (or ``DIR/selection.json``).
"""

from __future__ import annotations

import argparse
import json
import platform
import statistics
import time
from pathlib import Path

import numpy as np
import warp as wp

from dftl_warp.guides import bind, bind_groom, guide_points_of, select_guides
from dftl_warp.guides.deform import GuideDeformer


def fibonacci_sphere(n: int) -> np.ndarray:
    i = np.arange(n) + 0.5
    phi = np.arccos(1.0 - 2.0 * i / n)
    theta = np.pi * (1.0 + 5.0 ** 0.5) * i
    return np.stack([np.cos(theta) * np.sin(phi), np.cos(phi), np.sin(theta) * np.sin(phi)], axis=1)


def sphere_strands(normals: np.ndarray, n: int, curl: float, turns: float, radius=0.1, length=0.15,
                   chunk=1 << 16) -> np.ndarray:
    """(S * n, 3) float32 strands leaving the sphere along ``normals``, drooping under -Y, with a helix
    of radius ``curl`` around that line."""
    S = normals.shape[0]
    out = np.empty((S * n, 3), dtype=np.float32)
    t = np.linspace(0.0, 1.0, n)[None, :, None]
    down = np.array([0.0, -1.0, 0.0])
    for a in range(0, S, chunk):
        d = normals[a:a + chunk, None, :]
        ref = np.where(np.abs(d[..., 1:2]) < 0.9, np.array([0.0, 1.0, 0.0]), np.array([1.0, 0.0, 0.0]))
        u = np.cross(d, ref)
        u /= np.linalg.norm(u, axis=-1, keepdims=True)
        v = np.cross(d, u)
        line = radius * d + t * length * d + (t ** 2) * 0.4 * length * down
        if curl > 0:
            ph = t * turns * 2.0 * np.pi
            line = line + curl * ((np.cos(ph) - 1.0) * u + np.sin(ph) * v)
        out[a * n:(a + chunk) * n] = line.reshape(-1, 3)
    return out


def bench(args) -> dict:
    device = wp.get_device(args.device)
    n = args.vertices
    t0 = time.perf_counter()
    guides = sphere_strands(fibonacci_sphere(args.guides), n, 0.0, 0.0)
    rng = np.random.default_rng(0)
    normals = rng.normal(size=(args.render, 3))
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    render = sphere_strands(normals, n, args.curl, args.turns)
    t_groom = time.perf_counter() - t0
    t0 = time.perf_counter()
    binding = bind(guides, np.full(args.guides, n), render, np.full(args.render, n), k=args.k,
                   frames=args.frames, param=args.param, clump=args.clump, render_guides=np.full(args.render, -1))
    t_bind = time.perf_counter() - t0
    del render
    deformer = GuideDeformer(binding, device)
    del binding
    # one frame's guides: the whole groom turned by 30 degrees about Y, plus a per-vertex wiggle
    c, s = np.cos(0.5), np.sin(0.5)
    R = np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])
    moved = guides @ R.T + rng.normal(scale=1e-3, size=guides.shape) * (np.arange(guides.shape[0]) % n != 0)[:, None]
    gpu_guides = wp.array(moved.astype(np.float32), dtype=wp.vec3, device=device)
    out = wp.empty(deformer.num_render_points, dtype=wp.vec3, device=device)
    for _ in range(args.warmup):
        deformer.deform(gpu_guides, out=out)
    wp.synchronize_device(device)
    times = []
    for _ in range(args.repeats):
        a = time.perf_counter()
        deformer.deform(gpu_guides, out=out)
        wp.synchronize_device(device)
        times.append(time.perf_counter() - a)
    ms = statistics.median(times) * 1e3
    return {
        "device": str(device), "device_name": device.name, "guides": args.guides, "render": args.render,
        "vertices": n, "k": args.k, "frames": args.frames, "param": args.param, "clump": args.clump,
        "groom_build_s": round(t_groom, 3), "bind_s": round(t_bind, 3),
        "deform_ms_median": round(ms, 4), "deform_ms_min": round(min(times) * 1e3, 4),
        "repeats": args.repeats, "warmup": args.warmup,
        "render_vertices_per_s": round(deformer.num_render_points / (ms * 1e-3)),
        "binding_bytes": deformer.binding_nbytes(), "binding_bytes_per_render_strand": deformer.bytes_per_render_strand(),
        "guide_side_bytes": deformer.guide_nbytes(), "output_bytes": out.capacity,
        "warp": wp.__version__, "machine": platform.node(), "processor": platform.processor() or platform.machine(),
        "date": time.strftime("%Y-%m-%d"),
    }


def table(rows: list[dict]) -> str:
    head = ("| device | guides | render | vertices | k | frames | bind s | deform ms/frame (median) | "
            "render vertices/s | binding B/render strand | binding MB | guide-side MB |")
    lines = [head, "|" + "---|" * 12]
    for r in rows:
        lines.append(f"| {r['device_name']} | {r['guides']} | {r['render']} | {r['vertices']} | {r['k']} | {r['frames']} "
                     f"| {r['bind_s']:.1f} | {r['deform_ms_median']:.3f} | {r['render_vertices_per_s']:.3g} "
                     f"| {r['binding_bytes_per_render_strand']:.0f} | {r['binding_bytes'] / 2**20:.1f} "
                     f"| {r['guide_side_bytes'] / 2**20:.2f} |")
    return "\n".join(lines)


# ---- selection study: every strand simulated vs the guides simulated and the rest deformed

def turning_roots(roots: np.ndarray, steps: int, dt: float, up: int = 1, amplitude=np.pi / 3, period=2.0):
    """(steps + 1, S, 3) roots turned about the up axis through their centroid by amplitude sin(2 pi t / period)."""
    centre = roots.mean(axis=0)
    out = np.empty((steps + 1,) + roots.shape)
    a, b = [i for i in range(3) if i != up]
    for k in range(steps + 1):
        ang = amplitude * np.sin(2 * np.pi * k * dt / period)
        c, s = np.cos(ang), np.sin(ang)
        rel = roots - centre
        out[k] = roots
        out[k][:, a] = centre[a] + c * rel[:, a] + s * rel[:, b]
        out[k][:, b] = centre[b] - s * rel[:, a] + c * rel[:, b]
    return out


def selection(args) -> dict:
    from dftl_warp.importers import read_groom
    from dftl_warp.simulation.strands import simulate_strands

    groom = read_groom(args.selection)
    points = np.asarray(groom.points, dtype=np.float64) * args.scale
    counts = np.asarray(groom.counts, dtype=np.int64)
    starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
    tips = starts + counts - 1
    lengths = np.add.reduceat(np.r_[np.linalg.norm(np.diff(points, axis=0), axis=1), 0.0] *
                              np.isin(np.arange(points.shape[0]), tips, invert=True), starts)
    fps_, substeps = 24, args.substeps
    steps, dt = args.frames * substeps, 1.0 / (fps_ * substeps)
    roots = turning_roots(points[starts], steps, dt)
    common = dict(steps=steps, dt=dt, device=args.device, record_every=substeps)
    t0 = time.perf_counter()
    full = simulate_strands(points, counts, roots=roots, **common).positions
    t_full = time.perf_counter() - t0
    result = {"groom": str(args.selection), "param": args.param, "k": args.k, "frames_mode": args.frames_mode, "strands": int(counts.size), "points": int(points.shape[0]),
              "frames": args.frames, "substeps": substeps, "motion": "roots turn +-60 deg about Y over 2 s",
              "full_simulation_s": round(t_full, 2), "runs": []}
    for fraction in args.fractions:
        for method in ("fps", "kmeans"):
            t0 = time.perf_counter()
            g = select_guides(points, counts, fraction, method)
            t_sel = time.perf_counter() - t0
            gp, gc = guide_points_of(points, counts, g)
            groots = roots[:, g]
            t0 = time.perf_counter()
            sim = simulate_strands(gp, gc, roots=groots, **common).positions
            t_sim = time.perf_counter() - t0
            b = bind_groom(points, counts, g, k=args.k, frames=args.frames_mode, param=args.param)
            deformer = GuideDeformer(b, args.device)
            dist = np.stack([np.linalg.norm(deformer.deform_numpy(sim[f])[tips] - full[f][tips], axis=1)
                             for f in range(sim.shape[0])])
            keep = np.ones(counts.size, dtype=bool)
            keep[g] = False  # guides themselves are simulated exactly as in the full run... apart from hair-hair
            worst = dist.max(axis=0)[keep]
            rel = worst / lengths[keep]
            result["runs"].append({
                "method": method, "fraction": fraction, "guides": int(g.size), "select_s": round(t_sel, 3),
                "guide_simulation_s": round(t_sim, 2),
                "tip_distance_median_m": float(np.median(worst)), "tip_distance_p90_m": float(np.percentile(worst, 90)),
                "tip_distance_median_rel": float(np.median(rel)), "tip_distance_p90_rel": float(np.percentile(rel, 90)),
                "last_frame_tip_distance_median_m": float(np.median(dist[-1][keep])),
            })
    return result


def selection_table(r: dict) -> str:
    lines = ["| method | guides | median tip distance (mm) | p90 (mm) | median / length | p90 / length | last frame median (mm) |",
             "|---|---|---|---|---|---|---|"]
    for x in r["runs"]:
        lines.append(f"| {x['method']} | {x['guides']} ({x['fraction']:.0%}) | {x['tip_distance_median_m'] * 1e3:.2f} "
                     f"| {x['tip_distance_p90_m'] * 1e3:.2f} | {x['tip_distance_median_rel']:.3f} | {x['tip_distance_p90_rel']:.3f} "
                     f"| {x['last_frame_tip_distance_median_m'] * 1e3:.2f} |")
    return "\n".join(lines)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--device", default="cpu")
    ap.add_argument("--guides", type=int, default=100)
    ap.add_argument("--render", type=int, default=2000)
    ap.add_argument("--vertices", type=int, default=32)
    ap.add_argument("--k", type=int, default=4)
    ap.add_argument("--frames-mode", dest="frames_mode", choices=["blend", "per-guide"], default="blend")
    ap.add_argument("--param", choices=["length", "fraction"], default="length")
    ap.add_argument("--clump", type=float, default=0.0)
    ap.add_argument("--curl", type=float, default=0.003, help="helix radius of the render strands, m")
    ap.add_argument("--turns", type=float, default=4.0)
    ap.add_argument("--warmup", type=int, default=3)
    ap.add_argument("--repeats", type=int, default=20)
    ap.add_argument("--selection", type=Path, help="a hair file: measure guide selection against a full simulation")
    ap.add_argument("--fractions", type=float, nargs="+", default=[0.05, 0.1, 0.2])
    ap.add_argument("--frames", type=int, default=48, help="selection study: frames at 24 fps")
    ap.add_argument("--substeps", type=int, default=8)
    ap.add_argument("--scale", type=float, default=1.0, help="selection study: file units to metres")
    ap.add_argument("--out", type=Path, required=True)
    args = ap.parse_args(argv)
    wp.config.quiet = True
    wp.init()
    args.out.mkdir(parents=True, exist_ok=True)
    if args.selection:
        r = selection(args)
        print(selection_table(r))
        (args.out / "selection.json").write_text(json.dumps(r, indent=2))
        return 0
    args.frames = args.frames_mode
    r = bench(args)
    print(table([r]))
    (args.out / "bench_guides.json").write_text(json.dumps(r, indent=2))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
