#!/usr/bin/env python3
"""Cost and error of the hair-hair grid's variants against today's splat-every-substep (issue 20).

The groom is ``bench_features.py``'s (strands of 32 vertices, 1 cm segments, rooted on the upper
half of a 10 cm head, combed outward and down). The variants: the grid rebuilt every ``k``
substeps (``HairHair.splat_interval``, USD ``dftl:hairHairSplatInterval``; ``k`` = the substeps
of a frame: once per frame) and splatted one thread per particle (``splat="particles"``, today's)
or one thread per strand (``splat="strands"``: a strand's runs through a cell summed in registers).

- **cost**: ms per frame of 10 substeps (the fastest of the timed frames, and their median: a
  shared machine's load only ever adds; after 12 settling frames; a CUDA graph per frame on the
  GPU) against the bare step timed in the same run, for the 1 cm cells of
  ``docs/bench/h200/features-cuda0.md`` and the default cell (4 mean segments, 4 cm); then each
  phase of a rebuild and the sweep on their own, and how many node writes (each one density and
  three momentum atomics) a particle costs in each splat.
- **error**: RMS over particles of the position difference, as a fraction of the strand length,
  against ``k = 1`` (particles) at the same substeps and against a converged run (``k = 1`` at
  8 x the substeps; its own distance to 4 x the substeps is printed to show it converged), in two
  scenes where hair-hair matters: the groom falling from its combed pose (``fall``) and, from the
  pose it settles in (at rest), the head turning about the vertical at 2 rad/s (``turn``). Beside
  them: the hair-hair effect itself (friction and repulsion 0 instead), the error today's ``k = 1``
  makes against the converged run, the rounding floor (``splat="strands"`` at ``k = 1``, the same
  sums in another order; on the GPU the atomics' order also varies from run to run), and ``k > 1``
  without the centring of the grid on the substeps that use it ("not centred").

    python scripts/bench_hair_hair.py --device cpu --repeats 30 --out docs/bench/hair-hair-cpu
    python scripts/bench_hair_hair.py --device cuda:0 --strands 262144 --out $OUT

``--out`` gets ``hair-hair-<device>.md`` and ``.json``.
"""

from __future__ import annotations

import argparse
import datetime
import json
import statistics
import sys
from pathlib import Path

import numpy as np
import warp as wp

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_features import FPS, G, groom, machine_line, timed  # noqa: E402

import dftl_warp as dw  # noqa: E402
from dftl_warp import features as F  # noqa: E402
from dftl_warp.kernels.features.grid import grid_bounds_kernel, grid_reset_kernel  # noqa: E402

SUBSTEPS = 10
SETTLE_FRAMES = 12
SEGMENT = 0.01  # m, bench_features.groom's
VERTICES = 32
LENGTH = SEGMENT * (VERTICES - 1)  # m
#: (label, cell size m): the feature table's 1 cm cells, and the default (4 mean segments)
CELLS = (("1 cm cells", 0.01), ("default cells (4 segments, 4 cm)", 4 * SEGMENT))
SPLATS = ("particles", "strands")
#: error: frames at which positions are compared, the turn's rate (rad/s)
ERROR_FRAMES = (3, 6, 12)
TURN_RATE = 2.0


def intervals(substeps=SUBSTEPS):
    return tuple(sorted({1, 2, 5, substeps}))


def make(pts, counts, device, off=False, centred=True, **hair_hair):
    """(model, solver, state, control) of the groom with ``HairHair(**hair_hair)`` (``off``: no
    feature; ``centred=False``: a grid rebuilt every k substeps splatted at the positions themselves)."""
    feats = None if off else [F.HairHair(**hair_hair)]
    model = dw.Model.from_strands(pts, counts, device=device, features=feats)
    solver = dw.DFTLSolver(model, gravity=G, fused=False)
    if not off:
        solver._features._grid.centred = centred
    return model, solver, solver.state(), model.control()


# -- cost -----------------------------------------------------------------------------------------


def node_writes(model, positions, cell):
    """Node writes (of 4 atomics) per particle of the per-strand splat: at each change of cell a
    strand writes the 4 nodes it leaves after a step of one cell along one axis, else all 8, and at
    its end its last cell's 8 (the per-particle splat: 8 per particle)."""
    x = model.points_from_device(positions)
    ijk = np.floor((x - x.min(0)) / cell).astype(np.int64)
    starts = np.concatenate([[0], np.cumsum(model.counts)[:-1]])
    step = np.abs(np.diff(ijk, axis=0))
    moved = step.sum(axis=1)
    leave = np.where(moved == 0, 0, np.where((moved == 1), 4, 8))
    leave[starts[1:] - 1] = 0  # no change of cell across two strands
    return float((leave.sum() + 8 * len(starts)) / len(x))


def cost(device, strands, repeats):
    pts, counts, _ = groom(strands)
    dt = 1.0 / FPS / SUBSTEPS
    runs = [("bare DFTL step", None, make(pts, counts, device, off=True))]
    for label, cell in CELLS:
        for splat in SPLATS:
            for k in intervals():
                runs.append((f"{label}, splat {splat}, every {k} substep{'s' if k > 1 else ''}", (cell, splat, k),
                             make(pts, counts, device, cell_size=cell, splat=splat, splat_interval=k)))
    with wp.ScopedDevice(device):
        for _, _, (_, solver, state, control) in runs:
            for _ in range(SETTLE_FRAMES):
                solver.advance(state, control, dt, SUBSTEPS)
        times = {name: [] for name, _, _ in runs}
        for _ in range(repeats):  # rounds over all variants
            for name, _, (_, solver, state, control) in runs:
                times[name] += timed(lambda: solver.advance(state, control, dt, SUBSTEPS), device, 1)
    bare = min(times[runs[0][0]])
    rows = []
    for name, variant, _ in runs:
        ms = min(times[name]) * 1e3
        rows.append(dict(variant=name, ms_per_frame=ms, median_ms_per_frame=statistics.median(times[name]) * 1e3,
                         vs_bare=ms / (bare * 1e3),
                         cell=None if variant is None else variant[0],
                         splat=None if variant is None else variant[1],
                         interval=None if variant is None else variant[2]))
    for r in rows:
        today = next((q for q in rows if q["cell"] == r["cell"] and q["splat"] == "particles" and q["interval"] == 1),
                     None)
        r["vs_today"] = None if today is None else r["ms_per_frame"] / today["ms_per_frame"]
    return rows, phases(runs, device, dt, repeats)


def phases(runs, device, dt, repeats):
    """Each phase of a rebuild and the sweep on its own (ms per launch), per cell size."""
    out = []
    for label, cell in CELLS:
        by = {v[1]: r for _, v, r in runs if v is not None and v[0] == cell and v[2] == 1}
        model, solver, state, control = by["particles"]
        grid = solver._features._grid
        strands_grid = by["strands"][1]._features._grid
        g = grid.arrays
        head = solver.feature_head(control, dt, 1.0)
        pos, vel = state.positions, state.velocities
        reps = 10

        def launches(fn):
            return min(timed(lambda: [fn() for _ in range(reps)], device, repeats)) / reps * 1e3

        def old_bounds():
            wp.launch(grid_reset_kernel(model.scalar), dim=1, device=device, outputs=[g["lower"]])
            wp.launch(grid_bounds_kernel(model.scalar), dim=model.num_slots, device=device, inputs=[pos],
                      outputs=[g["lower"]])

        with wp.ScopedDevice(device):
            grid.bounds(pos)
            strands_grid.bounds(by["strands"][2].positions)
            rows = [
                ("clear (density and momentum)", launches(lambda: (g["density"].zero_(), g["momentum"].zero_()))),
                ("bounds, one thread per particle (before)", launches(old_bounds)),
                ("bounds, one thread per strand", launches(lambda: grid.bounds(pos))),
                ("clear + splat, one thread per particle", launches(lambda: grid.splat(pos, vel))),
                ("clear + splat, one thread per strand",
                 launches(lambda: strands_grid.splat(by["strands"][2].positions, by["strands"][2].velocities))),
                ("featured sweep (samples the grid)",
                 launches(lambda: solver._features.sweep(state, state, control, head))),
            ]
        writes = node_writes(model, pos, cell)
        out.append(dict(cells=label, grid_nodes=int(np.prod(grid.shape)), grid_mib=np.prod(grid.shape) * 16 / 2**20,
                        phases=rows, node_writes_per_particle={"particles": 8.0, "strands": writes}))
    return out


# -- error ----------------------------------------------------------------------------------------


def rotation_y(angle):
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def trajectory(pts, counts, roots, device, substeps, scene, start=None, **hair_hair):
    """Positions (input order, m) at :data:`ERROR_FRAMES` of ``scene`` ("fall" or "turn"), from the
    rest pose or, at rest, from positions ``start`` (device slot order, the same layout)."""
    model, solver, state, control = make(pts, counts, device, **hair_hair)
    if start is not None:
        state.write("positions", start)
    out = {}
    with wp.ScopedDevice(device):
        for f in range(max(ERROR_FRAMES)):
            if scene == "turn":
                a0, a1 = TURN_RATE * f / FPS, TURN_RATE * (f + 1) / FPS
                control.set_root_targets(roots @ rotation_y(a0).T, roots @ rotation_y(a1).T)
            solver.advance(state, control, 1.0 / FPS / substeps, substeps)
            if f + 1 in ERROR_FRAMES:
                out[f + 1] = model.points_from_device(state.positions)
    return out


def rms(a, b):
    """RMS position difference (fraction of the strand length) at each compared frame."""
    return [float(np.sqrt(np.mean(np.sum((a[f] - b[f]) ** 2, axis=1))) / LENGTH) for f in ERROR_FRAMES]


def error(device, strands, cell):
    pts, counts, roots = groom(strands)
    out = {}
    for scene in ("fall", "turn"):
        start = None
        if scene == "turn":  # the pose settled at k = 1, at rest (the same start for every substep count)
            _, solver, settled, control = make(pts, counts, device, cell_size=cell)
            with wp.ScopedDevice(device):
                for _ in range(2 * SETTLE_FRAMES):
                    solver.advance(settled, control, 1.0 / FPS / SUBSTEPS, SUBSTEPS)
            start = settled.positions.numpy()

        def run(substeps=SUBSTEPS, **kw):
            return trajectory(pts, counts, roots, device, substeps, scene, start, **{"cell_size": cell, **kw})

        today = run()
        ref, ref4 = run(8 * SUBSTEPS), run(4 * SUBSTEPS)
        lines = {
            "hair-hair effect (friction and repulsion 0 instead)": rms(run(friction=0.0, repulsion=0.0), today),
            "converged run: 4x vs 8x substeps": rms(ref4, ref),
            f"today (particles, every substep, {SUBSTEPS} substeps) vs converged": rms(today, ref),
        }
        variants = []
        for splat in SPLATS:
            for k in intervals():
                if splat == "particles" and k == 1:
                    continue
                x = run(splat=splat, splat_interval=k)
                variants.append(dict(splat=splat, interval=k, vs_today=rms(x, today), vs_converged=rms(x, ref)))
        for k in intervals()[1:]:  # the centring's worth
            x = run(splat_interval=k, centred=False)
            variants.append(dict(splat="particles, not centred", interval=k, vs_today=rms(x, today),
                                 vs_converged=rms(x, ref)))
        out[scene] = dict(reference=lines, variants=variants)
    return out


# -- report ---------------------------------------------------------------------------------------


def report(device, strands, error_strands, repeats):
    wp.config.quiet = True
    wp.init()
    device = wp.get_device(device)
    costs, phase_rows = cost(device, strands, repeats)
    errors = {label: error(device, error_strands, cell) for label, cell in CELLS}
    lines = [f"### Cost: {strands} strands x {VERTICES} vertices, {SUBSTEPS} substeps per frame; fastest of "
             f"{repeats} frames (median beside it) after {SETTLE_FRAMES} settling frames, rounds over all variants", "",
             "| variant | ms per frame | median | vs bare | vs today |", "|---|---:|---:|---:|---:|"]
    for r in costs:
        today = "-" if r["vs_today"] is None else f"{r['vs_today']:.2f}"
        lines.append(f"| {r['variant']} | {r['ms_per_frame']:.2f} | {r['median_ms_per_frame']:.2f} | "
                     f"{r['vs_bare']:.1f}x | {today} |")
    for p in phase_rows:
        lines += ["", f"Phases alone, {p['cells']} ({p['grid_nodes']} nodes, {p['grid_mib']:.1f} MiB); node writes "
                  f"(4 atomics each) per particle: particles 8, strands {p['node_writes_per_particle']['strands']:.2f}",
                  "", "| phase | ms per launch (fastest of the repeats of 10) |", "|---|---:|"]
        lines += [f"| {name} | {ms:.3f} |" for name, ms in p["phases"]]
    head = " | ".join(f"t = {f}/{FPS} s" for f in ERROR_FRAMES)
    for label, scenes in errors.items():
        for scene, e in scenes.items():
            lines += ["", f"### Error, {label}, scene '{scene}': {error_strands} strands; RMS position difference / "
                      f"strand length ({LENGTH:.2f} m)", "", f"| compared | {head} |",
                      "|---|" + "---:|" * len(ERROR_FRAMES)]
            lines += [f"| {name} | " + " | ".join(f"{v:.2e}" for v in vals) + " |"
                      for name, vals in e["reference"].items()]
            for v in e["variants"]:
                for against in ("vs_today", "vs_converged"):
                    lines.append(f"| {v['splat']}, every {v['interval']}: {against.replace('_', ' ')} | "
                                 + " | ".join(f"{x:.2e}" for x in v[against]) + " |")
    return lines, dict(device=machine_line(device), strands=strands, error_strands=error_strands, substeps=SUBSTEPS,
                       cost=costs, phases=phase_rows, error=errors)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--device", default="cpu")
    ap.add_argument("--out", default=None, help="folder for hair-hair-<device>.md and .json")
    ap.add_argument("--strands", type=int, default=None, help="cost groom (default 1000 on CPU, 262144 on CUDA)")
    ap.add_argument("--error-strands", type=int, default=None, help="error groom (default 200 on CPU, 20000 on CUDA)")
    ap.add_argument("--repeats", type=int, default=None, help="timed frames per variant (default 15 CPU, 20 CUDA)")
    args = ap.parse_args(argv)
    cuda = str(args.device).startswith("cuda")
    strands = args.strands or (262144 if cuda else 1000)
    error_strands = args.error_strands or (20000 if cuda else 200)
    repeats = args.repeats or (20 if cuda else 15)
    lines, data = report(args.device, strands, error_strands, repeats)
    stamp = f"{datetime.datetime.now(datetime.timezone.utc):%Y-%m-%d %H:%M} UTC"
    text = f"Hair-hair variants on {data['device']}, float32, prior correction, dt = 1/{FPS * SUBSTEPS} s; {stamp}.\n\n"
    text += "\n".join(lines) + "\n"
    print(text)
    if args.out:
        out = Path(args.out)
        out.mkdir(parents=True, exist_ok=True)
        tag = str(args.device).replace(":", "")
        (out / f"hair-hair-{tag}.md").write_text(text)
        (out / f"hair-hair-{tag}.json").write_text(json.dumps(data, indent=2))


if __name__ == "__main__":
    main()
