"""Write the study's GPU-scale front (:mod:`dftl_warp.study.front`): ``front.json``, ``front.md``
and ``front.png`` (error against ms/frame, log-log, one marker style per solver, the Pareto front
drawn, the preset targets marked).

:func:`write_front` takes :func:`~dftl_warp.study.front.measure_front`'s result and the run's
``meta`` (command, device, device name, machine, date); :func:`load_front` reads a ``front.json``
back, so the report can be redrawn (e.g. with other preset targets) without rerunning.
"""

from __future__ import annotations

import json
import warnings
from pathlib import Path

import numpy as np

from ..durable import write_file, write_text
from ..simulation.quality import QUALITY_PRESETS
from .front import PRESET_MAX_STRETCH, PRESET_TARGETS, pareto_front, pick_presets, preset_ineligible, presets_source

#: marker style per solver in the plot
MARKERS = {"dftl": "o", "ftl": "v", "pbd": "s", "rattle": "D", "reference": "^"}

#: why each preset's error target is what it is (the markdown's text; ``L``: the strand length)
TARGET_REASONS = {
    "draft": "a quarter of the length: the swing is there, with the right sense and roughly its "
             "amplitude (a groom that never moves scores {still:.2f}), for blocking and previews",
    "production": "one segment of the strand ({segment:.1%} of L for {particles} particles): the "
                  "error is below the groom's own spatial resolution",
    "reference": "{reference_mm:.2g} mm on a {length_m:g} m strand, a few hair diameters: "
                 "indistinguishable from the truth at a strand's thickness, for validation",
}


def _setting(row) -> str:
    return f"{row['label']} x{row['substeps']}"


def load_front(path) -> tuple[dict, dict]:
    """(result, meta) from a ``front.json`` written by :func:`write_front`."""
    data = json.loads(Path(path).read_text())
    return data["result"], data["meta"]


def plot_front(result: dict, front: list[int], picks: dict, path: Path) -> None:
    """Error against ms/frame, log-log: one marker style per solver, one colour per setting, the
    substeps next to each point, the Pareto front as a step line, the preset targets dotted and
    each preset's pick ringed."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = result["rows"]
    fig, ax = plt.subplots(figsize=(8.5, 6))
    labels = list(dict.fromkeys(r["label"] for r in rows))
    colours = plt.get_cmap("tab10")
    for n, label in enumerate(labels):
        rs = [r for r in rows if r["label"] == label and np.isfinite(r["error"]) and r["error"] > 0]
        if not rs:
            continue
        ax.loglog([r["ms_per_frame"] for r in rs], [r["error"] for r in rs], marker=MARKERS.get(rs[0]["solver"], "x"),
                  ms=5, lw=0.8, color=colours(n % 10), label=label,
                  ls="--" if "posterior" in label else "-")
        for r in rs:
            ax.annotate(str(r["substeps"]), (r["ms_per_frame"], r["error"]), fontsize=6, alpha=0.7,
                        xytext=(3, 2), textcoords="offset points")
    if front:
        xs = [rows[i]["ms_per_frame"] for i in front]
        ys = [rows[i]["error"] for i in front]
        ax.step(xs, ys, where="post", color="red", lw=4, alpha=0.25, label="Pareto front")
    ringed: dict = {}
    for name, p in picks.items():
        ax.axhline(p["target"], color="grey", lw=0.8, ls=":")
        ax.annotate(f"{name} target", (1.0, p["target"]), xycoords=("axes fraction", "data"), ha="right",
                    va="bottom", fontsize=7, color="grey")
        if p["row"] is not None:
            ringed.setdefault(p["row"], []).append(name)
    for i, names in ringed.items():  # each preset's pick, ringed
        r = rows[i]
        ax.scatter([r["ms_per_frame"]], [r["error"]], s=160, facecolors="none", edgecolors="black", lw=1.2)
        ax.annotate(", ".join(names), (r["ms_per_frame"], r["error"]), fontsize=7, weight="bold", xytext=(-6, -12),
                    textcoords="offset points", ha="right")
    g = result["groom"]
    ax.set_xlabel("ms per frame (median after the first)")
    ax.set_ylabel("max over frames of RMS position error / strand length")
    ax.set_title(f"{g['strands']} strands x {g['particles']} released at 45 degrees, {g['frames']} frames: "
                 "error against cost (labels: substeps per frame)", fontsize=9)
    ax.legend(fontsize=7)
    ax.grid(True, which="both", alpha=0.3)
    with warnings.catch_warnings():   # matplotlib's note that placing the legend "best" took long (a loaded
        # machine): two lines of Python's warning format on stderr, about matplotlib, not the input
        warnings.filterwarnings("ignore", message="Creating legend with loc", category=UserWarning)
        fig.tight_layout()
        fig.savefig(path, dpi=110)
    plt.close(fig)


def _current_presets(result: dict) -> list[list]:
    """Today's presets (QUALITY_PRESETS) as measured here, where a row matches them."""
    out = []
    for name, p in QUALITY_PRESETS.items():
        t = result["truth"]
        if (p["solver"], p["precision"], p["substeps"]) == (t["solver"], t["precision"], t["substeps"]):
            out.append([f"`{name}`", "the truth itself", "-", f"{t['ms_per_frame']:.3g}"])
            continue
        for r in result["rows"]:
            opts = r.get("options", {})
            same = (r["solver"], r["precision"], r["substeps"]) == (p["solver"], p["precision"], p["substeps"])
            if same and all(opts.get(k, v) == v for k, v in p.items() if k in ("damping", "correction")):
                out.append([f"`{name}`", _setting(r), f"{r['error']:.3g}", f"{r['ms_per_frame']:.3g}"])
                break
        else:
            out.append([f"`{name}`", "not measured here", "-", "-"])
    return out


def _table(header, rows) -> list[str]:
    return (["| " + " | ".join(header) + " |", "|" + "|".join("---" for _ in header) + "|"]
            + ["| " + " | ".join(str(c) for c in row) + " |" for row in rows])


def render_front(result: dict, meta: dict, front: list[int], picks: dict, image: str = "front.png") -> str:
    """The markdown report."""
    g, t, rows = result["groom"], result["truth"], result["rows"]
    length, particles = g["length"], g["particles"]
    ref32 = [r for r in rows if r["solver"] == "reference" and r["substeps"] == t["substeps"] // 2]
    own = (f"its own error, estimated as a third of the reference's at {t['substeps'] // 2} substeps "
           f"(second order), is {ref32[0]['error'] / 3:.1e}" if ref32 else "its own error is not estimated here")
    lines = [
        "# The front at scale: error against ms/frame for every solver",
        "",
        f"Measured by `dftl-warp study --front` (`dftl_warp/study/front.py`), command:",
        "",
        f"    {meta['command']}",
        "",
        "(`dftl-warp study --front-from front.json --out DIR` redraws this page and the plot from the json.)",
        "",
        f"on {meta['device_name']} (Warp device `{meta['device']}`), host {meta['machine']} ({meta['cpu']}, "
        f"{meta['cores']} cores), Warp {meta['warp']}, {meta['date']}, in {result['seconds']:.0f} s"
        + (" (the smoke subset)" if meta.get("fast") else "") + ".",
        "",
        f"**Groom**: {g['strands']} strands x {particles} particles, {length:g} m, rooted on a 0.1 m sphere, "
        f"released at 45 degrees from hanging to swing under gravity, roots still, {g['frames']} frames at 24 fps. "
        f"**Truth**: the float64 `reference` solver at {t['substeps']} substeps per frame "
        f"({t['ms_per_frame']:.3g} ms/frame); {own}. **Error**: the max over frames of the RMS over all "
        f"particles of the position error, divided by the strand length; a groom that never moves scores "
        f"{result['still_error']:.3f}. **Cost**: the median ms of `advance` per frame (device synchronized) "
        "over the frames after the first (compilation, graph capture). **Max stretch**: the largest "
        "`|l/l0 - 1|` over segments and frames.",
        "",
        f"![error against ms/frame]({image})",
        "",
        "## Every setting",
        "",
    ]
    on = set(front)
    table = [[r["label"], r["substeps"], f"{r['ms_per_frame']:.3g}", f"{r['error']:.3g}", f"{r['max_stretch']:.1e}",
              "" if r.get("fallbacks") is None else r["fallbacks"], "**yes**" if i in on else ""]
             for i, r in enumerate(rows)]
    lines += _table(["setting", "substeps", "ms/frame", "error", "max stretch", "rattle fallbacks", "on the front"],
                    table)
    lines += ["", "## The Pareto front", "",
              "The settings no other setting beats in both error and cost, cheapest first:", ""]
    lines += [f"- {_setting(rows[i])}: {rows[i]['ms_per_frame']:.3g} ms/frame, error {rows[i]['error']:.3g}"
              for i in front]
    mm = PRESET_TARGETS.get("reference", 0.001) * length * 1e3
    reasons = {k: v.format(still=result["still_error"], segment=1 / (particles - 1), particles=particles,
                           reference_mm=mm, length_m=length) for k, v in TARGET_REASONS.items()}
    lines += ["", "## Quality presets from the front", "",
              "Each preset is the cheapest measured setting whose error meets the preset's target and "
              f"that a preset can express: solver, substeps, precision and (DFTL) damping and correction, "
              f"the solver's other options at their defaults; lengths kept (max stretch <= {PRESET_MAX_STRETCH:g}); "
              "DFTL at s = 1 in the prior form only (s < 1 does not converge and creates energy at small "
              "steps, docs/accuracy.md sections 1 and 6; the posterior form's velocities are not the motion's, "
              "section 3). Targets (error / strand length):", ""]
    lines += [f"- `{name}` <= {p['target']:g}: {reasons.get(name, '')}" for name, p in picks.items()]
    lines += [""]
    picked = [[f"`{n}`", f"{p['target']:g}", _setting(rows[p["row"]]), f"{p['error']:.3g}", f"{p['ms_per_frame']:.3g}"]
              if p["row"] is not None else [f"`{n}`", f"{p['target']:g}", "none meets it", "-", "-"]
              for n, p in picks.items()]
    lines += _table(["preset", "target", "setting", "error", "ms/frame"], picked)
    lines += ["", "As `dftl_warp/simulation/quality.py` entries (`QUALITY_PRESETS`):", "", "```python",
              presets_source(picks), "```", "", "Today's presets, measured in this run:", ""]
    lines += _table(["preset", "setting", "error", "ms/frame"], _current_presets(result))
    skipped = sorted({(r["label"], preset_ineligible(r)) for r in rows if preset_ineligible(r)})
    if skipped:
        lines += ["", "Not eligible as presets:", ""] + [f"- {label}: {why}" for label, why in skipped]
    return "\n".join(lines) + "\n"


def write_front(result: dict, meta: dict, out, targets=None) -> list[str]:
    """Write ``front.json``, ``front.md`` and ``front.png`` into ``out`` (created); returns the paths.
    The json holds the result, the meta, the front (row indices) and the picked presets. All three
    are made first: a result they cannot be made from raises before anything is written."""
    import os
    import shutil
    import tempfile

    out = Path(out)
    rows = result["rows"]
    front = pareto_front(rows)
    picks = pick_presets(rows, targets)
    data = {"meta": meta, "result": result, "front": front, "presets": picks}
    paths = [out / "front.json", out / "front.md", out / "front.png"]
    fd, image = tempfile.mkstemp(suffix=".png")   # everything made before anything is written into out
    os.close(fd)
    try:
        text = json.dumps(data, indent=1, default=float), render_front(result, meta, front, picks)
        plot_front(result, front, picks, Path(image))
        out.mkdir(parents=True, exist_ok=True)
        write_text(paths[0], text[0])
        write_text(paths[1], text[1])
        write_file(paths[2], lambda tmp: shutil.copyfile(image, tmp))
    finally:
        if os.path.exists(image):
            os.unlink(image)
    return [str(p) for p in paths]
