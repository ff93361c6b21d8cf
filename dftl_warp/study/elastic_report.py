"""The accuracy study's elastic section: the plot ``elastic.png`` and the markdown of
:func:`dftl_warp.study.sweeps.elastic`'s rows (``results["elastic"]``, ``results["elastic_reference"]``)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..durable import write_file


def _by(rows, key):
    groups: dict = {}
    for r in rows:
        groups.setdefault(r[key], []).append(r)
    return groups


def local_orders(rows) -> list:
    """Observed order between successive substep counts: log(e_i / e_{i+1}) / log(k_{i+1} / k_i)."""
    return [float(np.log(a["error"] / b["error"]) / np.log(b["substeps"] / a["substeps"]))
            for a, b in zip(rows[:-1], rows[1:])]


def save_figure(fig, path) -> None:
    """Save the matplotlib figure ``fig`` to ``path`` (its suffix: the format) whole or not at all."""
    write_file(path, lambda tmp: fig.savefig(tmp, dpi=110))


def plot_elastic(results: dict, out) -> dict:
    """``elastic.png``: error against substeps per scenario (the reference's own error dashed)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    scenarios = _by(results["elastic"], "scenario")
    refs = {r["scenario"]: r for r in results["elastic_reference"]}
    fig, axes = plt.subplots(1, len(scenarios), figsize=(5.2 * len(scenarios), 4.2), squeeze=False)
    for ax, (name, rows) in zip(axes[0], scenarios.items()):
        for label, rs in _by(rows, "setting").items():
            ax.loglog([r["substeps"] for r in rs], [r["error"] for r in rs], marker="o", ms=4, label=label)
        ks = np.array(sorted({r["substeps"] for r in rows}), dtype=float)
        finish_convergence_axes(ax, name, ks, max(r["error"] for r in rows), refs[name]["self_error"])
    fig.tight_layout()
    save_figure(fig, Path(out) / "elastic.png")
    plt.close(fig)
    return {"elastic": "elastic.png"}


def finish_convergence_axes(ax, name: str, substeps, top: float, self_error: float) -> None:
    """The common dressing of an elastic-against-reference convergence plot: a first-order guide
    from ``top`` at the fewest ``substeps``, the reference's own error, labels, legend and grid."""
    ax.loglog(substeps, top * substeps[0] / substeps, color="grey", lw=0.8, ls="-.", label="first order")
    ax.axhline(self_error, color="black", lw=0.8, ls="--", label="reference's own error")
    ax.set_xlabel("substeps per 24 fps frame")
    ax.set_ylabel("trajectory error / strand length")
    ax.set_title(f"{name}: elastic solver against the elastic reference", fontsize=9)
    ax.legend(fontsize=7)
    ax.grid(True, which="both", alpha=0.3)


def _table(header, rows):
    lines = ["| " + " | ".join(header) + " |", "|" + "|".join("---" for _ in header) + "|"]
    lines += ["| " + " | ".join(str(c) for c in row) + " |" for row in rows]
    return "\n".join(lines)


def elastic_markdown(results: dict, img: str, number: int = 9) -> str:
    """The report's section on elastic strands (images linked as ``img`` + name)."""
    rows, refs = results["elastic"], results["elastic_reference"]
    ref_rows = [[r["scenario"], r["description"], r["particles"], f"{r['seconds']:g}", r["substeps"],
                 f"{r['dt'] * 1e6:.3g}", f"{r['step_limit'] * 1e6:.3g}", f"{r['self_error']:.1e}",
                 f"{r['ns_per_particle_step']:.3g}"] for r in refs]
    table, findings, last_order = [], [], {}
    for (name, label), rs in _by([dict(r, key=(r["scenario"], r["setting"])) for r in rows], "key").items():
        rs = sorted(rs, key=lambda r: r["substeps"])
        orders = [""] + [f"{p:+.2f}" for p in local_orders(rs)]
        for r, p in zip(rs, orders):
            table.append([name, label, r["substeps"], f"{r['dt'] * 1e3:.3g}", f"{r['error']:.3e}", p,
                          f"{r['max_stretch']:.1e}", f"{r['wall_s_per_s']:.3g}", f"{r['ns_per_particle_step']:.3g}"])
        if len(rs) >= 2:
            last = local_orders(rs)[-1]
            verdict = ("about first order" if last > 0.75 else "falling, slower than first order" if last > 0.2
                       else "not falling between the last two counts")
            findings.append(f"{name}, {label}: {rs[0]['error']:.3g} at {rs[0]['substeps']} substeps to "
                            f"{rs[-1]['error']:.3g} at {rs[-1]['substeps']}; last observed order {last:+.2f}: "
                            f"{verdict}.")
            last_order[(name, label)] = last
    stall = [name for (name, label), p in last_order.items() if label.startswith("elastic s=0") and p < 0.2
             and last_order.get((name, "elastic s=1 (default)"), 0.0) > 0.5]
    if stall:
        findings.append(
            f"On {', '.join(stall)} s = 0 (no follow-the-leader velocity correction) stops converging where the "
            "default s = 1 keeps going: the signature of DFTL's s < 1 in section 1 (docs/elastic.md, "
            "\"The reference with elastic energy\"; docs/elastic/convergence.md).")
    return f"""## {number}. Elastic strands: the elastic solver against the elastic reference

The `elastic` solver (docs/elastic.md; backward Euler with an implicit bending solve, first order)
against the `reference` solver with the same elastic energy (`ReferenceSolver(model,
elastic={{...}})`: RATTLE in float64 with the elastic solver's masses, bending and twist energy,
rest curvatures and clamped root, the frames at their minimiser for the current positions;
docs/elastic.md, "The reference with elastic energy"). 80 um human hair (E = 3.89 GPa, 1320 kg/m^3),
32 segments, float64. Error norm as above (max over the 24 fps frames of the RMS over particles,
divided by the strand length). The reference's bending force is explicit: it runs at half its
stability limit `2 / omega_max` (the stiffest bending mode), and its own error is its distance to a
run at twice its substeps:

{_table(["scenario", "what", "particles", "seconds", "reference substeps/frame", "dt (us)", "limit (us)",
         "reference's own error", "reference ns per particle-step"], ref_rows)}

![elastic solver against the elastic reference]({img}elastic.png)

{_table(["scenario", "setting", "substeps/frame", "dt (ms)", "error", "observed order", "max stretch",
         "wall s per simulated s", "ns per particle-step"], table)}

{chr(10).join("- " + f for f in findings)}

Cost: the elastic solver's wall time on this device for the copies of each scenario's strand side
by side (per particle-step, so independent of the count); the reference's is one strand, in one
launch per frame. Observed order: the slope of log(error) against log(substeps) between neighbours
(1 = first order)."""
