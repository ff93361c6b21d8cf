#!/usr/bin/env python3
"""Convergence of the elastic solver to the elastic reference over substeps, per damping s and
correction form: docs/elastic/convergence.md (+ .json, .png).

The scenarios are those of the accuracy study's elastic section (:func:`dftl_warp.study.sweeps.elastic`):
a straight cantilever of 80 um hair, L = l_b, released horizontal, and a styled helix (0.2 m, two turns)
on a root shaken 2 cm at 2 Hz; 32 segments, float64, 0.5 s. The truth is the ``reference`` solver with
the same elastic energy (RATTLE, float64, at a quarter of its stability limit). Error: the max over the
24 fps frames of the RMS position error over particles, divided by the strand length.

    python scripts/elastic_convergence.py --out docs/elastic            # minutes on 2 cores
    python scripts/elastic_convergence.py --substeps 8 32 --out /tmp/c  # a quick look
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

DAMPINGS = (0.0, 0.5, 1.0)
CORRECTIONS = ("prior", "posterior")
MACHINE = "2-core CPU VM"
DATE = "2026-11-24"


def label(damping: float, correction: str) -> str:
    return f"s={damping:g} {correction}"


def measure(substeps, scenarios, frames, log=print):
    """Rows of :func:`dftl_warp.study.sweeps.elastic` for every (s, correction), one strand per run."""
    from dftl_warp.study.sweeps import StudyConfig, elastic

    cfg = StudyConfig(device="cpu")
    cfg.elastic_scenarios = list(scenarios)
    cfg.elastic_frames = frames
    cfg.elastic_substeps = list(substeps)
    cfg.elastic_strands = 1
    cfg.elastic_settings = [(label(s, c), {"damping": s, "correction": c}) for c in CORRECTIONS for s in DAMPINGS]
    cfg.elastic_reference_fraction = 0.25
    return elastic(cfg, log)


def measure_equal_masses(substeps, frames, log=print):
    """The curly scenario with the tip's radius raised by sqrt(2), so that every free particle has
    the same mass (the hair's own tip carries half a segment's): rows and the reference row, as
    :func:`measure`, prior form only (the posterior form moves the strand identically)."""
    from dftl_warp.core.model import Model
    from dftl_warp.solvers import make_solver
    from dftl_warp.study import scenarios as sc
    from dftl_warp.study.sweeps import G, _elastic_scenario, trajectory_error

    rest, _, roots_of, description = _elastic_scenario("curly")
    n, frame = rest.shape[0], 1 / 24
    length = float(np.linalg.norm(np.diff(rest, axis=0), axis=1).sum())
    radius = np.r_[np.full(n - 1, sc.HAIR_RADIUS), sc.HAIR_RADIUS * np.sqrt(2.0)]
    roots = roots_of(rest[:1])

    def run(name, k, **options):
        model = Model.from_strands(rest, [n], device="cpu", precision="float64")
        return sc.record(make_solver(model, name, gravity=G, **options), frames, frame, k, roots=roots)[0]

    probe = make_solver(Model.from_strands(rest, [n], device="cpu", precision="float64"), "reference", gravity=G,
                        elastic={"radius": radius})
    k = int(np.ceil(frame / (0.25 * probe.elastic.step_limit)))
    truth = run("reference", k, elastic={"radius": radius})
    finer = run("reference", 2 * k, elastic={"radius": radius})
    name = "curly, equal masses"
    ref = {"scenario": name, "description": description.replace("styled helix", "styled helix, tip radius x sqrt 2"),
           "substeps": k, "self_error": trajectory_error(truth, finer, length)}
    rows = []
    for s in DAMPINGS:
        for substeps_ in substeps:
            error = trajectory_error(run("elastic", substeps_, radius=radius, damping=s), truth, length)
            rows.append({"scenario": name, "setting": label(s, "prior"), "damping": s, "substeps": substeps_,
                         "error": error})
            log(f"elastic: {name} {label(s, 'prior'):16s} x{substeps_:<4d} error {error:.3e}")
    return rows, ref


def orders(rows):
    """Local observed orders between successive substep counts, and the least-squares slope of
    log(error) against log(1/substeps) over the last three counts."""
    e = np.array([r["error"] for r in rows])
    k = np.array([r["substeps"] for r in rows], dtype=float)
    local = list(np.log(e[:-1] / e[1:]) / np.log(k[1:] / k[:-1]))
    tail = float(np.polyfit(np.log(k[-3:]), -np.log(e[-3:]), 1)[0]) if len(k) >= 3 else float("nan")
    return local, tail


def plot(rows, refs, out: Path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from dftl_warp.study.elastic_report import finish_convergence_axes

    names = list(dict.fromkeys(r["scenario"] for r in rows))
    fig, axes = plt.subplots(1, len(names), figsize=(5.6 * len(names), 4.4), squeeze=False)
    colours = {0.0: "tab:red", 0.5: "tab:orange", 1.0: "tab:blue"}
    for ax, name in zip(axes[0], names):
        ks = np.array(sorted({r["substeps"] for r in rows if r["scenario"] == name}), dtype=float)
        top = 0.0
        for c in CORRECTIONS:
            for s in DAMPINGS:
                rs = [r for r in rows if r["scenario"] == name and r["setting"] == label(s, c)]
                if not rs:
                    continue
                top = max(top, max(r["error"] for r in rs))
                ax.loglog([r["substeps"] for r in rs], [r["error"] for r in rs], color=colours[s],
                          ls="-" if c == "prior" else ":", marker="o" if c == "prior" else "s", ms=4,
                          label=label(s, c))
        ref = next(r for r in refs if r["scenario"] == name)
        finish_convergence_axes(ax, name, ks, top, ref["self_error"])
    fig.tight_layout()
    fig.savefig(out / "convergence.png", dpi=110)
    plt.close(fig)


def markdown(rows, refs, command: str, seconds: float) -> str:
    md = [f"Command: `{command}`; {MACHINE}; {DATE}; {seconds / 60:.1f} min.", "",
          "The elastic solver (float64) against the `reference` solver with the same elastic energy (RATTLE, "
          "float64, at a quarter of its stability limit), 80 um hair, 32 segments, 0.5 s. Error: max over the 24 fps "
          "frames of the RMS position error over particles / L. s = `damping` (DFTL's share of the "
          "follow-the-leader correction removed from the velocity), in the prior or posterior form.", "",
          "| scenario | what | reference substeps/frame | reference's own error |", "|---|---|---:|---:|"]
    md += [f"| {r['scenario']} | {r['description']} | {r['substeps']} | {r['self_error']:.1e} |" for r in refs]
    md += [""]
    names = list(dict.fromkeys(r["scenario"] for r in rows))
    summary = []
    for name in names:
        ks = sorted({r["substeps"] for r in rows if r["scenario"] == name})
        md += [f"### {name}", "", "Error / L (observed order against the previous count in brackets):", "",
               "| setting | " + " | ".join(str(k) for k in ks) + " | slope, last 3 |",
               "|---|" + "---:|" * (len(ks) + 1)]
        for c in CORRECTIONS:
            for s in DAMPINGS:
                rs = sorted((r for r in rows if r["scenario"] == name and r["setting"] == label(s, c)),
                            key=lambda r: r["substeps"])
                if not rs:
                    continue
                local, tail = orders(rs)
                cells = [f"{rs[0]['error']:.2e}"] + [f"{r['error']:.2e} ({p:+.2f})" for r, p in zip(rs[1:], local)]
                md += [f"| {label(s, c)} | " + " | ".join(cells) + f" | {tail:+.2f} |"]
                summary.append({"scenario": name, "setting": label(s, c), "first": rs[0]["error"],
                                "last": rs[-1]["error"], "tail_order": tail})
        md += [""]
    md += ["![error against substeps](convergence.png)", "",
           "Slope, last 3: the least-squares slope of log(error) against log(substeps) over the three finest "
           "counts (1 = first order, 0 = no convergence).", "", "Per setting, coarsest to finest count:", ""]
    md += [f"- {r['scenario']}, {r['setting']}: {r['first']:.2e} -> {r['last']:.2e}, slope over the last three "
           f"{r['tail_order']:+.2f}" for r in summary]
    md += ["", "Reading (see docs/elastic.md, \"The reference with elastic energy\"): the prior and posterior forms "
           "subtract the same s c_{i+1} / h from particle i's velocity, at the end of a step or the start of the "
           "next, so they move the strand identically (their rows agree to round-off; only the written "
           "velocities differ). With s < 1 the part (1 - s) c / h of the follow-the-leader correction stays in "
           "the velocity, an O(h) error every step: its sum over a fixed time does not vanish, the error stops "
           "falling and then rises. With s = 1 the error falls at about first order until, on the shaken curl, "
           "it levels off. The floor is the tip's: the follow-the-leader projection and its correction s c / h "
           "take no account of the masses, and the hair's tip carries half a segment's mass; with the tip's mass "
           "made equal (\"curly, equal masses\") s = 1 keeps about first order to the finest count."]
    return "\n".join(md) + "\n", summary


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="docs/elastic")
    ap.add_argument("--substeps", type=int, nargs="+", default=[8, 16, 32, 64, 128, 256, 512, 1024, 2048, 4096, 8192])
    ap.add_argument("--scenarios", nargs="+", default=["cantilever", "curly"])
    ap.add_argument("--frames", type=int, default=12, help="24 fps frames simulated (default 12: 0.5 s)")
    args = ap.parse_args()
    import warp as wp

    wp.config.quiet = True
    wp.init()
    command = "python scripts/elastic_convergence.py" + ("" if args.out == "docs/elastic" else f" --out {args.out}")
    if args.substeps != ap.get_default("substeps"):
        command += " --substeps " + " ".join(map(str, args.substeps))
    if args.scenarios != ap.get_default("scenarios"):
        command += " --scenarios " + " ".join(args.scenarios)
    if args.frames != 12:
        command += f" --frames {args.frames}"
    start = time.perf_counter()
    rows, refs = measure(sorted(args.substeps), args.scenarios, args.frames)
    if "curly" in args.scenarios:
        more, ref = measure_equal_masses(sorted(args.substeps), args.frames)
        rows, refs = rows + more, refs + [ref]
    seconds = time.perf_counter() - start
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    text, summary = markdown(rows, refs, command, seconds)
    (out / "convergence.json").write_text(json.dumps(
        {"command": command, "machine": MACHINE, "date": DATE, "rows": rows, "references": refs,
         "summary": summary}, indent=1))
    (out / "convergence.md").write_text(text)
    plot(rows, refs, out)
    print(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
