#!/usr/bin/env python3
"""Folded, fast strands: does DFTL with s = 1 lose energy there too?

The stability map (docs/accuracy.md, section 6) releases straight strands; on it DFTL with s = 1
never created energy. This probe starts strands folded tighter than a right angle at every joint
and moving fast, as a collider leaves them when it drags hair through itself, and measures their
*available energy* (kinetic plus gravitational above the strand hanging from its root, J/kg: the
energy monitor's, ``dftl_warp/simulation/monitor.py``) over one second at several substep counts.

The strands (``dftl_warp.study.scenarios.folded_strands``): ``--strands`` of 16 points 5 mm apart
from a fixed root; each joint turns by an angle drawn in [100, 175] degrees about a random axis;
every free particle gets a random velocity, each component normal with deviation ``--speed`` m/s.
Gravity -9.81 m/s^2 along y, 24 frames a second.

Runs, on the CPU device:
- ``dftl``: DFTL, s = 1, the prior form (the default); ``dftl posterior``: the paper's form;
- ``reference``: the inextensible chain integrated by RATTLE in float64 at ``--reference-substeps``
  (1024) a frame, where it conserves energy: what the true dynamics does from the same start. Its
  energy after the first frame (the first step projects away the velocity along the segments that
  the random start gives) is each strand's *true energy*. RATTLE is itself unstable at coarse steps
  on such strands (at 32 substeps a frame it gains energy too), so it runs at its own count;
- ``elastic``: the elastic solver (its rest shape is the folded start);
- ``dftl, tension carried only`` (diagnostic, numpy: ``dftl_warp.solvers.numpy_baseline.step``):
  DFTL whose carried correction keeps only the links that pulled (a follower's correction toward
  its leader), the pushes dropped.

Per run and substep count: the strands whose energy at some frame is more than twice their true
energy, the median over strands of that largest ratio, how far the particles move in a step over
the last half second (the RMS speed over a strand's free particles, times the step, over the
segment length; median over strands), and the strands the energy monitor flagged (its budget:
twice the start's energy, velocities along the segments included). Writes ``folded.md`` and
``folded.csv`` to ``--out``.

    python scripts/probe_dftl_folded.py --out docs/accuracy
"""

from __future__ import annotations

import argparse
import csv
import platform
import sys
import time
import warnings
from datetime import datetime, timezone
from pathlib import Path

import numpy as np

POINTS, SEGMENT, FPS, FRAMES, G = 16, 0.005, 24, 24, 9.81
SUBSTEPS = (4, 8, 16, 32, 64, 128, 256)


def run_solver(kind: str, points, velocities, count: int, substeps: int, frames: int = FRAMES):
    """Per frame and strand (frames x count): the available energy (J/kg) and the RMS speed of the
    free particles (m/s); per strand, whether the energy monitor flagged it."""
    import dftl_warp as dw
    from dftl_warp.simulation.monitor import EnergyGrowthWarning, EnergyMonitor

    precision = "float64" if kind == "reference" else "float32"
    model = dw.Model.from_strands(points, [POINTS] * count, widths=1e-4, device="cpu", precision=precision)
    name, options = {"dftl": ("dftl", {}), "dftl posterior": ("dftl", {"correction": "posterior"}),
                     "reference": ("reference", {}), "elastic": ("elastic", {})}[kind]
    solver = dw.make_solver(model, name, gravity=(0.0, -G, 0.0), **options)
    state, control = solver.state(), model.control()
    state.velocities.assign(model.points_to_device(velocities, relative=False))
    monitor = EnergyMonitor(solver, f"{kind} {substeps} substeps", state)
    energies, speeds = [], []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", EnergyGrowthWarning)
        for frame in range(frames):
            solver.advance(state, control, 1.0 / FPS / substeps, substeps)
            monitor.check(state, frame)
            energies.append(monitor.verdicts()[0])
            v = model.points_from_device(state.velocities, relative=False).reshape(count, POINTS, 3)
            speeds.append(np.sqrt((v[:, 1:] ** 2).sum(axis=2).mean(axis=1)))
    return np.array(energies), np.array(speeds), monitor.unstable.copy()


def run_tension_only(points, velocities, count: int, substeps: int):
    """The numpy DFTL (s = 1, prior form) with the carried correction of pushing links dropped."""
    from dftl_warp.solvers.numpy_baseline import pad_strands, step

    counts = np.full(count, POINTS)
    x = pad_strands(points, counts)
    v = pad_strands(velocities, counts)
    corr = np.zeros_like(x)
    rest = np.zeros((count, POINTS))
    rest[:, 1:] = np.linalg.norm(np.diff(x, axis=1), axis=2)
    hanging = x[:, :1, 1] - np.cumsum(rest, axis=1)
    dt = 1.0 / FPS / substeps
    energies, speeds = [], []
    for _ in range(FRAMES):
        for _ in range(substeps):
            x, v, corr = step(x, v, corr, rest, counts, x[:, 0], dt=dt, gravity=(0.0, -G, 0.0))
            link = x[:, 1:] - x[:, :-1]
            pushed = np.einsum("sij,sij->si", corr[:, 1:], link) > 0.0   # the follower moved away from its leader
            corr[:, 1:][pushed] = 0.0
        energy = 0.5 * (v[:, 1:] ** 2).sum(axis=(1, 2)) + G * (x[:, 1:, 1] - hanging[:, 1:]).sum(axis=1)
        energies.append(energy)
        speeds.append(np.sqrt((v[:, 1:] ** 2).sum(axis=2).mean(axis=1)))
    return np.array(energies), np.array(speeds), None


def summarize(energies, speeds, flagged, true_energy, substeps):
    """(strands whose energy at some frame exceeded twice their true energy, median largest ratio,
    median of the last half second's RMS particle speed in segments per step, flagged)."""
    ratio = energies.max(axis=0) / true_energy
    per_step = np.median(speeds[FRAMES // 2:].mean(axis=0)) / FPS / substeps / SEGMENT
    return (int((ratio > 2.0).sum()), float(np.median(ratio)), float(per_step),
            None if flagged is None else int(flagged.sum()))


def reading(rows, counts) -> str:
    """What the table says, with its figures."""
    def row(kind, k):
        return next(r for r in rows if r["run"] == kind and r["substeps"] == k)

    thrash = [k for k in counts if row("dftl", k)["energy_doubled"] > row("dftl", k)["strands"] // 2
              and row("dftl", k)["segments_per_step"] > 0.5]
    if not thrash:
        return "**Reading.** No count thrashed in this run: DFTL with s = 1 kept within twice the true energy."
    ratios = ", ".join(f"{row('dftl', k)['median_largest_ratio']:.3g}x at {k}" for k in thrash)
    speeds = ", ".join(f"{row('dftl', k)['segments_per_step']:.2f}" for k in thrash)
    flagged = ", ".join(f"{row('dftl', k)['monitor_flagged']} of {row('dftl', k)['energy_doubled']} at {k}"
                        for k in thrash)
    calm = [k for k in counts if k not in thrash]
    forms = "in both forms" if all(row("dftl posterior", k)["energy_doubled"] > row("dftl", k)["strands"] // 2
                                   for k in thrash) else "in the prior form"
    others = ", ".join(f"{row('dftl', k)['median_largest_ratio']:.2f}x at {k}" for k in calm)
    tension = max(r["median_largest_ratio"] for r in rows if r["run"] == "dftl, tension carried only")
    return (f"**Reading.** DFTL with s = 1, {forms}, *thrashes* from these starts at {thrash[0]} to "
            f"{thrash[-1]} substeps a frame: its particles settle into moving {speeds} of a segment every step, "
            f"so the energy a strand holds grows with the square of the substep count (median peak {ratios} "
            "the true dynamics' energy), where the true dynamics keeps its energy. At the other counts its strands "
            f"end moving at most {max(row('dftl', k)['segments_per_step'] for k in calm):.2f} of a segment a step "
            f"(median peak {others}); the elastic solver, a rod whose rest shape is the fold, loses energy at "
            "every count. Dropping the carried "
            "correction of the links that push, keeping the pulls, removes the thrash at every count (largest "
            f"median ratio {tension:.2f}): the pump is a follower's lagged push on its leader. That variant is a "
            "diagnostic, not a remedy: the true chain's links push as well, and without those forces DFTL would "
            "not converge to it where they matter. The energy monitor flagged "
            f"{flagged} substeps (its budget, twice the start's energy, counts the velocity along the segments "
            "that the first step removes).")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--strands", type=int, default=24)
    parser.add_argument("--speed", type=float, default=0.7, help="deviation of each velocity component, m/s")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--substeps", type=int, nargs="+", default=list(SUBSTEPS))
    parser.add_argument("--reference-substeps", type=int, default=1024)
    parser.add_argument("--out", type=Path, default=Path("docs/accuracy"))
    args = parser.parse_args(argv)
    import warp as wp

    wp.config.quiet = True
    from dftl_warp.study.scenarios import folded_strands

    points, velocities = folded_strands(args.strands, POINTS, SEGMENT, args.speed, args.seed)
    kinds = ("dftl", "dftl posterior", "elastic", "dftl, tension carried only")
    rows, started = [], time.time()
    reference, _, _ = run_solver("reference", points, velocities, args.strands, args.reference_substeps)
    true_energy = reference[0]
    drift = float(np.abs(reference / true_energy - 1.0).max())
    for kind in kinds:
        for substeps in args.substeps:
            if kind == "dftl, tension carried only":
                energies, speeds, flagged = run_tension_only(points, velocities, args.strands, substeps)
            else:
                energies, speeds, flagged = run_solver(kind, points, velocities, args.strands, substeps)
            grew, median, per_step, warned = summarize(energies, speeds, flagged, true_energy, substeps)
            rows.append({"run": kind, "substeps": substeps, "strands": args.strands, "energy_doubled": grew,
                         "median_largest_ratio": round(median, 4), "segments_per_step": round(per_step, 4),
                         "monitor_flagged": "" if warned is None else warned})
            print(rows[-1], file=sys.stderr)
    args.out.mkdir(parents=True, exist_ok=True)
    with open(args.out / "folded.csv", "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    stamp = datetime.now(timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    command = "python scripts/probe_dftl_folded.py " + " ".join(argv if argv is not None else sys.argv[1:])
    lines = [f"`{command.strip()}` ({platform.machine()} CPU, {stamp}, {time.time() - started:.0f} s). "
             f"{args.strands} strands of {POINTS} points {SEGMENT * 1e3:g} mm apart, folded by 100-175 degrees at "
             f"every joint, velocity components of deviation {args.speed:g} m/s; one second at {FPS} fps. "
             "Cells: strands whose energy at some frame exceeded twice their true energy / median of the largest "
             "ratio / median RMS particle speed over the last half second, in segments per step / strands the "
             "energy monitor flagged. The true energy is the reference's (RATTLE, float64, "
             f"{args.reference_substeps} substeps a frame), which stays within {drift:.1e} of itself over the "
             "second.", "",
             "| run | " + " | ".join(f"{k} substeps" for k in args.substeps) + " |",
             "|---|" + "---:|" * len(args.substeps)]
    for kind in kinds:
        cells = []
        for r in (r for r in rows if r["run"] == kind):
            flagged = "-" if r["monitor_flagged"] == "" else r["monitor_flagged"]
            cells.append(f"{r['energy_doubled']} / {r['median_largest_ratio']:.2f} / {r['segments_per_step']:.2f} / "
                         f"{flagged}")
        lines.append(f"| {kind} | " + " | ".join(cells) + " |")
    lines += ["", reading(rows, args.substeps)]
    (args.out / "folded.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    sys.exit(main())
