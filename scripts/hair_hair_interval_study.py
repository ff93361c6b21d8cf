#!/usr/bin/env python3
"""The production scene's error when the hair-hair grid is rebuilt every k substeps, against the
step's own time-discretisation error (issue 20: "measure the result against today's
splat-every-substep").

The DFTL production scene of ``bench_features.py`` (deforming body through its field, hair-hair on
1 cm cells, wind with curl noise and drag) runs from the groom's combed rest pose for ``--frames``
frames: at 10 substeps a frame with the grid rebuilt every substep (k = 1, the default) and every
k = 2, 5, 10 substeps, and at 40 and 80 substeps with k = 1 (the reference: the converged motion).
The table gives each run's RMS distance (over the particles, in strand lengths, 31 cm) to the
reference and, after the slash, to the default run (k = 1, 10 substeps) at a few frames, and its
wall time per substep. "Chaos" is the k = 1 run started with its
velocities scaled by 1 + 1e-6: how far round-off alone carries the scene apart (contacts and noise
make it chaotic), below which no difference means anything.

    python scripts/hair_hair_interval_study.py --device cuda:0 --strands 100000
    python scripts/hair_hair_interval_study.py --device cpu --strands 1000000 --patch 1000 --frames 6
"""

from __future__ import annotations

import argparse
import datetime
import sys
import time
from pathlib import Path

import numpy as np
import warp as wp

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_features import FPS, build_scene, machine_line, patched_groom, scenarios  # noqa: E402

from dftl_warp import features as F  # noqa: E402

ROW = "production scene:"
LENGTH = 0.31  # m: the groom's strands (32 vertices 1 cm apart)


def run(pts, counts, feats, extra, device, substeps, at, interval=1, kick=0.0):
    """Positions (input order) at the frames ``at`` and the wall seconds per substep."""
    feats = [F.HairHair(cell_size=f.cell_size, friction=f.friction, repulsion=f.repulsion, splat_interval=interval)
             if isinstance(f, F.HairHair) else f for f in feats]
    with wp.ScopedDevice(device):
        model, solver, state, control = build_scene(pts, counts, feats, extra, device)
        body = extra["body_frames"]
        dt = 1.0 / FPS / substeps
        out, seconds = {}, 0.0
        for f in range(max(at)):
            control.features.set_mesh_points(0, body[(f + 1) % len(body)])
            control.features.set_frame_time(f / FPS, (f + 1) / FPS)
            wp.synchronize_device(device)
            t = time.perf_counter()
            solver.advance(state, control, dt, substeps)
            wp.synchronize_device(device)
            seconds += time.perf_counter() - t
            if kick and f == 0:   # the hair starts at rest: perturb the velocities after the first frame
                state.velocities.assign(state.velocities.numpy() * (1.0 + kick))
            if f + 1 in at:
                out[f + 1] = model.points_from_device(state.positions, relative=False)
    return out, seconds / (max(at) * substeps)


def rms(a, b):
    return float(np.sqrt(np.mean(np.sum((a - b) ** 2, axis=1)))) / LENGTH


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--device", default="cpu")
    ap.add_argument("--strands", type=int, default=100_000)
    ap.add_argument("--patch", type=int, default=None, help="keep only this many strands (bench_features.patch)")
    ap.add_argument("--frames", type=int, nargs="+", default=[2, 5, 10], help="frames at which to compare")
    ap.add_argument("--out", default=None, help="folder for hair-hair-interval-<device>.md")
    args = ap.parse_args(argv)
    wp.config.quiet = True
    wp.init()
    device = wp.get_device(args.device)
    pts, counts, roots = patched_groom(args.strands, args.patch)
    (name, feats, extra), = [r for r in scenarios(pts, counts, roots) if r[0].startswith(ROW)]
    at = sorted(set(args.frames))
    reference, _ = run(pts, counts, feats, extra, device, 80, at)
    runs = [("**k = 1, 10 substeps (the default)**", dict(substeps=10)), ("k = 1, 40 substeps", dict(substeps=40)),
            ("chaos: k = 1, 10 substeps, velocities x (1 + 1e-6) after frame 1", dict(substeps=10, kick=1e-6))]
    runs += [(f"k = {k}, 10 substeps", dict(substeps=10, interval=k)) for k in (2, 5, 10)]
    size = f"{len(counts)} strands" + (f" (a patch of a {args.strands}-strand groom)" if args.patch else "")
    lines = [f"Hair-hair grid rebuilt every k substeps, production scene ({size} x 32), on {machine_line(device)}; "
             f"{datetime.datetime.now(datetime.timezone.utc):%Y-%m-%d %H:%M} UTC; RMS distance to the 80-substep "
             "run (k = 1) / to the default run, in strand lengths.", "",
             f"`python scripts/hair_hair_interval_study.py {' '.join(sys.argv[1:] if argv is None else argv)}`", "",
             "| run | " + " | ".join(f"frame {f} ({f / FPS:.2f} s)" for f in at) + " | wall ms per substep |",
             "|---|" + "---:|" * (len(at) + 1)]
    default = None
    for label, kw in runs:
        got, seconds = run(pts, counts, feats, extra, device, kw["substeps"], at, kw.get("interval", 1),
                           kw.get("kick", 0.0))
        cells = []
        for f in at:
            to_default = "" if default is None else f" / {rms(got[f], default[f]):.2e}"
            cells.append(f"{rms(got[f], reference[f]):.2e}{to_default}")
        lines.append(f"| {label} | " + " | ".join(cells) + f" | {seconds * 1e3:.3f} |")
        print(lines[-1], flush=True)
        if default is None and kw["substeps"] == 10:
            default = got
    text = "\n".join(lines) + "\n"
    print(text)
    if args.out:
        Path(args.out).mkdir(parents=True, exist_ok=True)
        (Path(args.out) / f"hair-hair-interval-{device.alias.replace(':', '')}-{len(counts)}.md").write_text(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
