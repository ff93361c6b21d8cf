"""The study at scale: error against cost of every solver and setting on a large groom (issue 19).

The groom (:func:`released_groom`): ``strands`` straight strands of ``particles`` points and
``length`` m rooted on a 0.1 m sphere, released at 45 degrees from hanging (rotated about z around
their roots) to swing under gravity, roots still, ``frames`` frames at 24 fps. Every setting runs
it from rest and is compared, frame by frame, with the float64 ``reference`` solver at
``reference_substeps`` substeps per frame (the truth).

- **Error** (dimensionless): the max over frames of the RMS over all particles of the position
  error, divided by the strand length (:func:`dftl_warp.study.sweeps.trajectory_error`'s norm).
- **Cost**: the median wall-clock ms of ``solver.advance`` per frame (device synchronized) over the
  frames after the first (the first includes kernel compilation and CUDA graph capture).
- **Max stretch**: the largest ``|l / l0 - 1|`` over segments and frames (``solver.diagnostics``).

:class:`FrontBench` runs settings on one groom (models shared per precision and correction form);
:func:`measure_front` runs a list of :class:`Setting` (:data:`FRONT_SETTINGS`, or
:data:`SMOKE_SETTINGS` for a CPU check in seconds); :func:`pareto_front` marks the settings no
other beats in both error and cost; :func:`pick_presets` re-derives the ``--quality`` presets from
the measured rows (:data:`PRESET_TARGETS`). :mod:`dftl_warp.study.front_report` writes the json,
markdown and plot. ``dftl-warp study --front`` and ``scripts/bench_rattle.py`` both run it.
"""

from __future__ import annotations

import inspect
import time
from dataclasses import dataclass, field

import numpy as np

from . import scenarios as sc

#: gravity, m/s^2, along -Y
GRAVITY = (0.0, -sc.GRAVITY, 0.0)
FRAME_DT = 1.0 / 24.0
POWERS_OF_TWO = tuple(2**k for k in range(10))  # 1 ... 512


@dataclass(frozen=True)
class Setting:
    """One solver configuration, run at each of ``substeps`` (per 1/24 s frame)."""

    label: str
    solver: str
    precision: str
    options: dict = field(default_factory=dict)
    substeps: tuple = ()


#: every solver and setting of the GPU-scale front (sized to run in ~3-4 min on one H200 at
#: 100k x 32: docs/accuracy-h200/front.md)
FRONT_SETTINGS = [
    Setting("DFTL prior s=1 f32", "dftl", "float32", {"damping": 1.0, "correction": "prior"}, POWERS_OF_TWO),
    Setting("DFTL posterior s=1 f32", "dftl", "float32", {"damping": 1.0, "correction": "posterior"}, POWERS_OF_TWO),
    Setting("DFTL prior s=0.5 f32", "dftl", "float32", {"damping": 0.5, "correction": "prior"}, POWERS_OF_TWO),
    Setting("DFTL posterior s=0.5 f32", "dftl", "float32", {"damping": 0.5, "correction": "posterior"},
            POWERS_OF_TWO),
    Setting("PBD K=4 f32", "pbd", "float32", {"iterations": 4}, (4, 16, 64, 256)),
    Setting("PBD K=16 f32", "pbd", "float32", {"iterations": 16}, (16, 64)),
    Setting("rattle f32", "rattle", "float32", {}, (1, 2, 4, 8, 16, 32)),
    Setting("rattle f32 2 Newton", "rattle", "float32", {"newton_iterations": 2}, (8, 16, 32)),
    Setting("reference f64", "reference", "float64", {}, (4, 8, 16, 32)),
]

#: the CPU smoke subset: every solver once, a few substeps (seconds at 64 strands x 3 frames)
SMOKE_SETTINGS = [
    Setting("DFTL prior s=1 f32", "dftl", "float32", {"damping": 1.0, "correction": "prior"}, (1, 8, 64)),
    Setting("DFTL posterior s=1 f32", "dftl", "float32", {"damping": 1.0, "correction": "posterior"}, (8,)),
    Setting("DFTL prior s=0.5 f32", "dftl", "float32", {"damping": 0.5, "correction": "prior"}, (8,)),
    Setting("PBD K=4 f32", "pbd", "float32", {"iterations": 4}, (8,)),
    Setting("rattle f32", "rattle", "float32", {}, (8,)),
    Setting("reference f64", "reference", "float64", {}, (8, 16)),
]


def released_groom(strands: int, particles: int, length: float, angle: float = np.pi / 4):
    """(points (N, 3), counts (S,)): :func:`~dftl_warp.study.scenarios.groom` hanging straight down,
    every strand rotated by ``angle`` (rad) about z around its root, i.e. released ``angle`` from
    hanging. Lengths in metres."""
    pts, counts = sc.groom(strands, particles, length, hanging=True)
    roots = np.repeat(pts[sc.strand_starts(counts)], counts, axis=0)
    c, s = np.cos(angle), np.sin(angle)
    rot = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    return roots + (pts - roots) @ rot.T, counts


class FrontBench:
    """Runs solver settings on one groom and measures each against a truth trajectory.

    ``points``/``counts`` as for :meth:`Model.from_strands <dftl_warp.core.model.Model.from_strands>`;
    ``length`` (m) divides the errors. Models are built once per (precision, carried corrections),
    each with the layout that ``dftl-warp simulate`` would give that solver.
    """

    def __init__(self, points, counts, *, device: str, frames: int, length: float, frame_dt: float = FRAME_DT):
        if int(frames) < 1:
            raise ValueError(f"frames must be >= 1, got {frames}")
        self.points = np.asarray(points, dtype=np.float64)
        self.counts = np.asarray(counts, dtype=np.int64)
        self.device, self.frames, self.length, self.frame_dt = device, int(frames), float(length), float(frame_dt)
        self._models: dict = {}
        self._gathers: dict = {}
        #: the truth: (frames + 1, N, 3) float64 world positions in input order, or None
        self.truth = None
        #: the error of a groom that never moves: the scale the errors are read against
        self.still_error = None

    def model(self, precision: str, corrections: bool):
        from ..core.model import Model

        key = (precision, bool(corrections))
        if key not in self._models:
            self._models[key] = Model.from_strands(self.points, self.counts, device=self.device, precision=precision,
                                                   corrections=corrections)
        return self._models[key]

    def positions(self, model, state) -> np.ndarray:
        """The state's positions, (N, 3) in input order and world space, in the model's precision
        (float64 once the origin is added): gathered on the device (an indexed copy), then one
        copy of N points to the host, so a frame of 100k strands costs milliseconds, not a host
        gather of the whole slot array. The array is reused by the next call."""
        import warp as wp

        g = self._gathers.get(id(model))
        if g is None:
            d, n = model.device, model.num_points
            slots = wp.array(model.layout.slot_of_point.astype(np.int32), dtype=wp.int32, device=d)
            gathered = wp.empty(n, dtype=model.vec3, device=d)
            host = wp.empty(n, dtype=model.vec3, device="cpu", pinned=True) if d.is_cuda else gathered
            g = self._gathers[id(model)] = (slots, gathered, host)
        slots, gathered, host = g
        wp.copy(gathered, wp.indexedarray(state.positions, [slots]))
        if host is not gathered:
            wp.copy(host, gathered)
        wp.synchronize_device(model.device)
        x = host.numpy().reshape(-1, 3)
        return x + model.origin if np.any(model.origin) else x

    def run(self, solver: str, precision: str, substeps: int, options=None, observe=None) -> dict:
        """Run one setting from rest over the frames; returns ``ms_per_frame``, ``max_stretch``,
        ``finite``, ``fallbacks`` (rattle; else None) and, with a truth, ``error`` and ``errors``
        (per frame). ``observe(frame, positions)`` sees every frame's positions (frame 0: the start)."""
        import warp as wp

        from ..solvers import carries_corrections, make_solver

        options = dict(options or {})
        model = self.model(precision, carries_corrections(solver, options.get("correction", "prior")))
        s = make_solver(model, solver, gravity=GRAVITY, **options)
        state, control = s.state(), model.control()
        dt = self.frame_dt / substeps
        clock, stretch, errors, finite = [], 0.0, [], True

        def look(frame):
            nonlocal finite
            x = self.positions(model, state)
            if self.truth is not None:  # a finite sum of squares has finite terms: no separate check
                d = np.subtract(x, self.truth[frame], dtype=np.float64)
                errors.append(float(np.sqrt(np.einsum("ij,ij->", d, d) / d.shape[0])) / self.length)
                finite = finite and bool(np.isfinite(errors[-1]))
            else:
                finite = finite and bool(np.isfinite(x).all())
            if observe is not None:
                observe(frame, x.copy())

        look(0)
        for f in range(self.frames):
            start = time.perf_counter()
            s.advance(state, control, dt, substeps)
            wp.synchronize_device(model.device)
            clock.append(time.perf_counter() - start)
            diag = s.diagnostics(state)
            stretch = max(stretch, float(diag["max_stretch"]))
            look(f + 1)
        timed = clock[1:] if len(clock) > 1 else clock
        out = {"ms_per_frame": 1000.0 * float(np.median(timed)), "max_stretch": stretch, "finite": finite,
               "fallbacks": diag.get("fallbacks")}
        if self.truth is not None:
            out["errors"] = errors
            out["error"] = max(errors) if finite else float("inf")
        return out

    def set_truth(self, substeps: int) -> dict:
        """Run the float64 reference at ``substeps`` per frame and keep its trajectory as the truth;
        returns its run (cost, stretch) and sets :attr:`still_error`."""
        frames = []
        result = self.run("reference", "float64", substeps, observe=lambda f, x: frames.append(x))
        self.truth = np.stack(frames)
        d = self.truth - self.truth[0]
        self.still_error = float(np.sqrt((d * d).sum(-1).mean(-1)).max()) / self.length
        return result


def measure_front(*, strands: int = 100_000, particles: int = 32, frames: int = 12, length: float = 0.2,
                  reference_substeps: int = 64, settings=None, device: str = "cpu", log=print) -> dict:
    """Run every setting (default :data:`FRONT_SETTINGS`) on the released groom against the truth.

    Returns ``{"rows": [...], "truth": {...}, "still_error": float, "seconds": float, "groom": {...}}``;
    each row: label, solver, precision, options, substeps, dt (s), ms_per_frame, error, max_stretch,
    finite, fallbacks.
    """
    started = time.perf_counter()
    pts, counts = released_groom(strands, particles, length)
    bench = FrontBench(pts, counts, device=device, frames=frames, length=length)
    truth = bench.set_truth(reference_substeps)
    log(f"front: {strands} strands x {particles}, truth: reference f64 x{reference_substeps} "
        f"{truth['ms_per_frame']:.3g} ms/frame; a still groom scores {bench.still_error:.3f}")
    rows = []
    for st in settings if settings is not None else FRONT_SETTINGS:
        for k in st.substeps:
            r = bench.run(st.solver, st.precision, k, st.options)
            rows.append({"label": st.label, "solver": st.solver, "precision": st.precision, "options": dict(st.options),
                         "substeps": int(k), "dt": FRAME_DT / k, "ms_per_frame": r["ms_per_frame"],
                         "error": r["error"], "max_stretch": r["max_stretch"], "finite": r["finite"],
                         "fallbacks": r["fallbacks"]})
            log(f"front: {st.label:26s} x{k:<4d} {r['ms_per_frame']:9.3f} ms/frame  error {r['error']:.3e}  "
                f"stretch {r['max_stretch']:.1e}")
    return {"rows": rows, "still_error": bench.still_error, "seconds": time.perf_counter() - started,
            "truth": {"solver": "reference", "precision": "float64", "substeps": int(reference_substeps),
                      "ms_per_frame": truth["ms_per_frame"], "max_stretch": truth["max_stretch"]},
            "groom": {"strands": int(strands), "particles": int(particles), "frames": int(frames),
                      "length": float(length), "release_angle_deg": 45.0, "fps": 24}}


# -- the Pareto front ---------------------------------------------------------------------------

def pareto_front(rows) -> list[int]:
    """Indices (ascending cost) of the rows no other row beats: none has both a cost
    (``ms_per_frame``) and an ``error`` at most its own with one of them smaller. Rows with a
    non-finite error or cost are never on the front."""
    ok = [i for i, r in enumerate(rows) if np.isfinite(r["error"]) and np.isfinite(r["ms_per_frame"])]
    front = []
    for i in ok:
        ci, ei = rows[i]["ms_per_frame"], rows[i]["error"]
        beaten = any(rows[j]["ms_per_frame"] <= ci and rows[j]["error"] <= ei
                     and (rows[j]["ms_per_frame"] < ci or rows[j]["error"] < ei) for j in ok)
        if not beaten:
            front.append(i)
    return sorted(front, key=lambda i: (rows[i]["ms_per_frame"], rows[i]["error"]))


# -- quality presets from the front -------------------------------------------------------------

#: error target of each ``--quality`` preset: RMS position error / strand length, max over the
#: frames (why these: docs/accuracy-h200/front.md, "Quality presets from the front")
PRESET_TARGETS = {"draft": 0.25, "production": 0.03, "reference": 0.001}

#: largest relative stretch a preset may show: every preset keeps lengths (no visible stretch)
PRESET_MAX_STRETCH = 1.0e-3

#: the keys of a preset (:data:`dftl_warp.simulation.quality.QUALITY_PRESETS`); ``damping`` and
#: ``correction`` for DFTL only
PRESET_KEYS = ("solver", "damping", "correction", "substeps", "precision")


def _non_default_options(solver: str, options: dict) -> dict:
    """The options of ``options`` whose value differs from the solver class's default."""
    from ..solvers import solver_class

    params = inspect.signature(solver_class(solver).__init__).parameters
    return {k: v for k, v in options.items() if k not in params or params[k].default != v}


def preset_ineligible(row) -> str | None:
    """Why a measured row cannot be a ``--quality`` preset, or None when it can: a preset sets only
    solver, substeps, precision and (DFTL) damping and correction (every other option at the
    solver's default), keeps lengths, must not create energy (DFTL s = 1) and writes the motion's
    velocities (DFTL's prior form)."""
    if not row.get("finite", True) or not np.isfinite(row["error"]):
        return "not finite"
    if row["max_stretch"] > PRESET_MAX_STRETCH:
        return f"stretches (max stretch above {PRESET_MAX_STRETCH:g})"
    options = row.get("options", {})
    extra = _non_default_options(row["solver"], options)
    if row["solver"] in ("dftl", "ftl"):
        extra = {k: v for k, v in extra.items() if k not in ("damping", "correction")}
        if float(options.get("damping", 1.0)) != 1.0 or row["solver"] == "ftl":
            return "damping s < 1 does not converge and creates energy at small steps (docs/accuracy.md 1, 6)"
        if options.get("correction", "prior") != "prior":
            return ("the posterior form's velocities are not the motion's (docs/accuracy.md 3); its positions "
                    "equal the prior form's at s = 1")
    if extra:
        return "options a preset cannot set: " + ", ".join(f"{k}={v}" for k, v in extra.items())
    return None


def preset_dict(row) -> dict:
    """A measured row as a :data:`~dftl_warp.simulation.quality.QUALITY_PRESETS` entry."""
    p = {"solver": row["solver"]}
    if row["solver"] == "dftl":
        opts = row.get("options", {})
        p["damping"] = float(opts.get("damping", 1.0))
        p["correction"] = opts.get("correction", "prior")
    p["substeps"] = int(row["substeps"])
    p["precision"] = row["precision"]
    return p


def pick_presets(rows, targets=None) -> dict:
    """For each preset of ``targets`` (name -> error target; default :data:`PRESET_TARGETS`), the
    cheapest eligible measured row (:func:`preset_ineligible`) whose error meets the target:
    ``{name: {"target", "row" (index or None), "preset" (dict or None), "error", "ms_per_frame"}}``."""
    targets = PRESET_TARGETS if targets is None else targets
    eligible = [i for i, r in enumerate(rows) if not r.get("truth") and preset_ineligible(r) is None]
    picks = {}
    for name, target in targets.items():
        meets = [i for i in eligible if rows[i]["error"] <= target]
        best = min(meets, key=lambda i: (rows[i]["ms_per_frame"], rows[i]["error"])) if meets else None
        picks[name] = {"target": float(target), "row": best,
                       "preset": preset_dict(rows[best]) if best is not None else None,
                       "error": rows[best]["error"] if best is not None else None,
                       "ms_per_frame": rows[best]["ms_per_frame"] if best is not None else None}
    return picks


def presets_source(picks) -> str:
    """The ``QUALITY_PRESETS = {...}`` text for ``dftl_warp/simulation/quality.py`` of ``picks``
    (:func:`pick_presets`); a preset with no pick is left out with a comment."""
    lines = ["QUALITY_PRESETS = {"]
    for name, p in picks.items():
        if p["preset"] is None:
            lines.append(f"    # {name}: no measured setting meets {p['target']:g}")
            continue
        body = ", ".join(f"{k!r}: {v!r}" for k, v in p["preset"].items())
        lines.append(f"    {name!r}: {{{body}}},  # error {p['error']:.2e}, {p['ms_per_frame']:.3g} ms/frame")
    lines.append("}")
    return "\n".join(lines).replace("'", '"')
