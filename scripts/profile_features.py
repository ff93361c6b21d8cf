#!/usr/bin/env python3
"""Where a featured scene's GPU time goes: the time of each kernel per step, from Warp's CUDA
activity timing (``wp.timing_begin``), for the rows of ``bench_features.py`` (the production
scenes by default).

The scenes, their settling and the frame loop are ``bench_features.py``'s. After settling, each
scene runs ``--frames`` frames with its substeps launched one by one (not through the CUDA graph
``advance`` replays, whose kernels the activity timer does not see one by one), the deforming
body's per-frame update (``set_mesh_points``) included. Each kernel's GPU time is summed over the
frames and divided by the substeps; "share" is its part of the summed kernel time. The bare DFTL
step of the same run is the first row of every table's reference.

    python scripts/profile_features.py --device cuda:0 --out $OUT
    python scripts/profile_features.py --device cuda:0 --strands 1000000 --only "production scene:" --out $OUT
    python scripts/profile_features.py --device cuda:0 --strands 1000000 --only "production scene with" \
        --elastic-caps 128 168 0 --out $OUT
"""

from __future__ import annotations

import argparse
import collections
import datetime
import shlex
import sys
import time
from pathlib import Path

import numpy as np
import warp as wp

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_features import (ELASTIC, FPS, SETTLE_FRAMES, SUBSTEPS, body_frames, body_mesh, build_scene,  # noqa: E402
                            groom, machine_line, scenarios)

from dftl_warp import features as F  # noqa: E402
from dftl_warp.kernels.solvers import elastic as elastic_kernels  # noqa: E402
from dftl_warp.kernels.solvers import featured as featured_kernels  # noqa: E402
from dftl_warp.kernels.features import air_grid as pass_kernels  # noqa: E402
from dftl_warp.kernels.features import grid_strands as splat_kernels  # noqa: E402
import dftl_warp.features.step as feature_step  # noqa: E402
from dftl_warp.features import hair_hair  # noqa: E402
from dftl_warp.solvers import elastic as elastic_solver  # noqa: E402

#: the rows profiled by default (name prefixes of ``bench_features.scenarios``)
DEFAULT_ROWS = ("bare DFTL step", "deforming body mesh", "hair-hair", "wind with curl noise", "production scene",
                "elastic strands")


def combinations():
    """Rows of the production scene's features two at a time, with DFTL and with elastic strands
    (``--combinations``): which pairs cost more together than apart."""
    dirs, tris = body_mesh()
    deform = dict(body_frames=body_frames(dirs, int(round(2.0 * FPS))))

    def field():
        return F.Colliders([F.TriangleMesh(points=deform["body_frames"][0], indices=tris, sdf=True)])

    def noise():
        return [F.Drag(1.0), F.Wind(velocity=(1.0, 0, 0), noise_amplitude=0.5)]

    rows = []
    for solver, extra in (("DFTL", {}), ("elastic", dict(ELASTIC))):
        rows += [
            (f"{solver}: field + hair-hair", [field(), F.HairHair(cell_size=0.01)], dict(deform, **extra)),
            (f"{solver}: field + wind with curl noise + drag", [field(), *noise()], dict(deform, **extra)),
            (f"{solver}: hair-hair + wind with curl noise + drag", [F.HairHair(cell_size=0.01), *noise()], dict(extra)),
        ]
        if solver == "elastic":
            rows += [("elastic: field", [field()], dict(deform, **extra)),
                     ("elastic: hair-hair", [F.HairHair(cell_size=0.01)], dict(extra)),
                     ("elastic: wind with curl noise + drag", noise(), dict(extra))]
    return rows


def build(pts, counts, feats, extra, device):
    """The scene of one row: model, solver, state, control and its one-frame function (settled)."""
    model, solver, state, control = build_scene(pts, counts, feats, extra, device)
    frames = extra.get("body_frames")
    dt = 1.0 / FPS / SUBSTEPS
    clock = [0]

    def one_frame(graph=True):
        if frames is not None:
            clock[0] += 1
            control.features.set_mesh_points(0, frames[clock[0] % len(frames)])
        if graph:
            solver.advance(state, control, dt, SUBSTEPS)
        else:
            solver.substeps(state, control, dt, SUBSTEPS)

    for _ in range(SETTLE_FRAMES):
        one_frame()
    return one_frame


def profile(one_frame, device, frames):
    """{kernel name: (launches per step, GPU seconds per step)} and the wall seconds per step."""
    one_frame(graph=False)  # compile anything the graph path did not
    wp.synchronize_device(device)
    wp.timing_begin(cuda_filter=wp.TIMING_ALL, synchronize=True)
    t = time.perf_counter()
    for _ in range(frames):
        one_frame(graph=False)
    wp.synchronize_device(device)
    wall = (time.perf_counter() - t) / (frames * SUBSTEPS)
    results = wp.timing_end(synchronize=True)
    per = collections.defaultdict(lambda: [0, 0.0])
    for r in results:
        per[r.name][0] += 1
        per[r.name][1] += r.elapsed * 1e-3  # ms -> s
    steps = frames * SUBSTEPS
    return {k: (n / steps, s / steps) for k, (n, s) in per.items()}, wall


def table(name, kernels, wall, bare):
    total = sum(s for _, s in kernels.values())
    rows = [f"### {name}", "",
            f"Kernel time {total * 1e3:.3f} ms per step ({total / bare:.1f}x the bare step's kernel time), "
            f"wall time launching substep by substep {wall * 1e3:.3f} ms per step.", "",
            "| kernel | launches per step | ms per step | x bare | share |", "|---|---:|---:|---:|---:|"]
    for k, (n, s) in sorted(kernels.items(), key=lambda kv: -kv[1][1]):
        rows.append(f"| `{k}` | {n:.2f} | {s * 1e3:.4f} | {s / bare:.2f}x | {100 * s / total:.1f}% |")
    return rows + [""]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--device", default="cuda:0")
    ap.add_argument("--strands", type=int, default=None, help="groom size (default 100k)")
    ap.add_argument("--frames", type=int, default=5, help="frames profiled per row")
    ap.add_argument("--only", nargs="*", default=None, help="rows whose names start with one of these "
                    f"(default: {', '.join(DEFAULT_ROWS)}); the bare row always runs")
    ap.add_argument("--combinations", action="store_true",
                    help="also the production scene's features two at a time, and the elastic solver's one at a time")
    ap.add_argument("--elastic-caps", type=int, nargs="*", default=None,
                    help="profile the elastic rows under each of these CUDA register caps of the float32 "
                         "kernel (0: none; kernels/solvers/elastic.py: CUDA_MAX_REGISTERS_F32)")
    ap.add_argument("--sweep-caps", type=int, nargs="*", default=None,
                    help="profile the DFTL rows with features under each of these CUDA register caps of the "
                         "featured sweep (0: none; kernels/solvers/featured.py: CUDA_MAX_REGISTERS)")
    ap.add_argument("--block-dims", type=int, nargs="*", default=None,
                    help="profile the rows with features at each of these CUDA block sizes of the sweep, the "
                         "elastic step and the splat (SWEEP_BLOCK_DIM of dftl_warp/features/step.py, "
                         "SPLAT_BLOCK_DIM of dftl_warp/features/hair_hair.py)")
    ap.add_argument("--aux-caps", type=int, nargs="*", default=None,
                    help="profile the rows with features under each of these CUDA register caps of the hair-hair "
                         "splat and the velocity pass (0: none; CUDA_MAX_REGISTERS of kernels/features/"
                         "grid_strands.py and air_grid.py)")
    ap.add_argument("--velocity-pass", choices=("on", "off", "both"), default="on",
                    help="hair-hair, drag and wind in their own pass before the sweep (on, the default), in the "
                         "sweep (off; dftl_warp/features/step.py: VELOCITY_PASS), or each row both ways")
    ap.add_argument("--out", default=None, help="folder for profile-<device>.md")
    args = ap.parse_args(argv)
    wp.config.quiet = True
    wp.init()
    device = wp.get_device(args.device)
    if not device.is_cuda:
        print(f"profile_features.py: {args.device} is not a CUDA device (the kernel timer is CUDA's)", file=sys.stderr)
        return 2
    strands = args.strands or 100_000
    pts, counts, roots = groom(strands)
    rows = scenarios(pts, counts, roots)
    only = tuple(args.only or DEFAULT_ROWS)
    rows = rows[:1] + [r for r in rows[1:] if r[0].startswith(only)]
    if args.combinations:
        rows += combinations()
    out = [f"Kernel times on {machine_line(device)}; {strands} strands x 32 vertices "
           f"({int(np.sum(counts))} particles), float32, dt = 1/{FPS * SUBSTEPS} s, {args.frames} frames of "
           f"{SUBSTEPS} substeps per row after {SETTLE_FRAMES} settling frames; "
           f"{datetime.datetime.now(datetime.timezone.utc):%Y-%m-%d %H:%M} UTC.", "",
           f"`python scripts/profile_features.py {shlex.join(sys.argv[1:] if argv is None else argv)}`", ""]
    todo = []
    passes = {"on": [True], "off": [False], "both": [False, True]}[args.velocity_pass]
    for name, feats, extra in rows:
        elastic = extra.get("solver") == "elastic"
        caps = (args.elastic_caps if elastic else args.sweep_caps if feats else None) or [None]
        blocks = (args.block_dims if feats else None) or [None]
        ways = passes if feats and args.velocity_pass == "both" else passes[-1:]
        for on in ways:
            label = name if len(ways) == 1 else f"{name}, velocity pass {'on' if on else 'off'}"
            for cap in caps:
                for block in blocks:
                    for aux in (args.aux_caps if feats and args.aux_caps else [None]):
                        tag = label if cap is None else f"{label}, register cap {cap or 'none'}"
                        tag = tag if block is None else f"{tag}, {block} threads per block"
                        tag = tag if aux is None else f"{tag}, splat and pass capped at {aux or 'none'}"
                        todo.append((tag, feats, extra, cap, on, block, aux))
    default_cap = dict(elastic_kernels.CUDA_MAX_REGISTERS_F32)
    default_sweep_cap = featured_kernels.CUDA_MAX_REGISTERS
    default_block = feature_step.SWEEP_BLOCK_DIM
    default_splat_block = hair_hair.SPLAT_BLOCK_DIM
    default_elastic_block = elastic_solver.ELASTIC_BLOCK_DIM
    bare = None
    for name, feats, extra, cap, on, block, aux in todo:
        started = time.perf_counter()
        splat_kernels.CUDA_MAX_REGISTERS = pass_kernels.CUDA_MAX_REGISTERS = aux or None
        splat_kernels.grid_splat_strands_kernel.cache_clear()
        pass_kernels.velocity_features_kernel.cache_clear()
        feature_step.VELOCITY_PASS = on
        feature_step.SWEEP_BLOCK_DIM = default_block if block is None else block
        hair_hair.SPLAT_BLOCK_DIM = default_splat_block if block is None else block
        elastic_solver.ELASTIC_BLOCK_DIM = default_elastic_block if block is None else block
        elastic = extra.get("solver") == "elastic"
        elastic_kernels.CUDA_MAX_REGISTERS_F32.update(
            default_cap if cap is None or not elastic else dict.fromkeys(default_cap, cap or None))
        featured_kernels.CUDA_MAX_REGISTERS = default_sweep_cap if cap is None or elastic else (cap or None)
        elastic_kernels.elastic_kernel.cache_clear()
        featured_kernels.featured_step_kernel.cache_clear()
        with wp.ScopedDevice(device):
            one_frame = build(pts, counts, feats, extra, device)
            kernels, wall = profile(one_frame, device, args.frames)
        total = sum(s for _, s in kernels.values())
        bare = bare or total
        out += table(name, kernels, wall, bare)
        print(f"{name}: {total * 1e3:.3f} ms per step of kernel time ({time.perf_counter() - started:.1f} s)",
              flush=True)
        if args.out:  # after every row: a run cut short keeps what it measured
            Path(args.out).mkdir(parents=True, exist_ok=True)
            (Path(args.out) / f"profile-{device.alias.replace(':', '')}-{strands}.md").write_text("\n".join(out) + "\n")
    print("\n".join(out))
    return 0


if __name__ == "__main__":
    sys.exit(main())
