"""The accuracy study: measure the speed-accuracy trade of every solver setting.

:func:`run_study` runs five sweeps on standard scenarios (:mod:`dftl_warp.study.scenarios`) and
returns their rows; :mod:`dftl_warp.study.report` turns them into CSV, PNG and markdown.

1. ``convergence``: the falling horizontal chain (10 particles, 1 m, 0.5 s) against the
   reference, over substeps, for DFTL (s, correction form, precision), FTL and PBD (K);
2. ``energy``: the same chain over 3 s at 1/240 s, energy against time;
3. ``groom``: a groom on a turning, nodding head over 0.5 s against the reference: error, stretch
   and wall time (the Pareto front), the quality presets;
4. ``modes``: a hanging chain started in a mode shape: period and damping per solver;
5. ``stability``: a map over (s, dt, particles per strand) of where runs create energy;
6. ``elastic``: elastic strands (a cantilever of human hair released horizontal, a styled curl on
   a shaken root): the ``elastic`` solver over substeps against the reference solver with the same
   elastic energy (``reference`` with ``elastic=``): error, stretch and cost.

Error norm everywhere: the max over recorded frames of the RMS over particles of the position
error, divided by the strand length (dimensionless).
"""

from __future__ import annotations

import time
import warnings
from dataclasses import dataclass, field

import numpy as np

from . import scenarios as sc
from ..core.model import Model
from ..simulation.monitor import EnergyMonitor
from ..simulation.quality import QUALITY_PRESETS
from ..solvers import make_solver
from ..solvers.elastic import HAIR_DENSITY, HAIR_E

G = (0.0, -sc.GRAVITY, 0.0)


@dataclass
class StudyConfig:
    """Sizes of the sweeps; :meth:`fast` is the CI subset."""

    device: str = "cpu"
    chain_particles: int = 10
    chain_length: float = 1.0
    chain_horizon: float = 0.5
    chain_frames: int = 20
    chain_substeps: list = field(default_factory=lambda: [5, 10, 20, 40, 80, 160, 320])
    chain_reference_substeps: int = 2560
    chain_settings: list = field(default_factory=lambda: [
        ("dftl s=1 prior f64", "dftl", {"damping": 1.0, "correction": "prior"}, "float64"),
        ("dftl s=1 posterior f64", "dftl", {"damping": 1.0, "correction": "posterior"}, "float64"),
        ("dftl s=1 prior f32", "dftl", {"damping": 1.0, "correction": "prior"}, "float32"),
        ("dftl s=0.9 f64", "dftl", {"damping": 0.9}, "float64"),
        ("dftl s=0.8 f64", "dftl", {"damping": 0.8}, "float64"),
        ("ftl (s=0) f64", "ftl", {}, "float64"),
        ("pbd K=1 f64", "pbd", {"iterations": 1}, "float64"),
        ("pbd K=4 f64", "pbd", {"iterations": 4}, "float64"),
        ("pbd K=16 f64", "pbd", {"iterations": 16}, "float64"),
        ("rattle f32", "rattle", {}, "float32"),
        ("rattle f64", "rattle", {}, "float64"),
    ])
    energy_seconds: float = 3.0
    energy_substeps: int = 10  # per 1/24 s frame: 1/240 s
    groom_strands: int = 1024  # enough work per launch that the CPU timing measures computation
    groom_particles: int = 16
    groom_length: float = 0.2
    groom_frames: int = 12  # 0.5 s: beyond ~1 s the undamped true dynamics is chaotic under the forcing
    groom_reference_substeps: int = 128
    groom_settings: list = field(default_factory=lambda: [
        ("dftl s=1 f32", "dftl", {"damping": 1.0}, "float32", [1, 2, 4, 8, 16, 32, 64, 128]),
        ("dftl s=1 f64", "dftl", {"damping": 1.0}, "float64", [1, 4, 16]),
        ("dftl s=1 posterior f32", "dftl", {"damping": 1.0, "correction": "posterior"}, "float32", [4]),
        ("dftl s=0.9 f32", "dftl", {"damping": 0.9}, "float32", [1, 4, 16, 64]),
        ("ftl (s=0) f32", "ftl", {}, "float32", [1, 4, 16]),
        ("pbd K=1 f32", "pbd", {"iterations": 1}, "float32", [1, 4, 16]),
        ("pbd K=4 f32", "pbd", {"iterations": 4}, "float32", [1, 4, 16]),
        ("pbd K=16 f32", "pbd", {"iterations": 16}, "float32", [1, 4, 16]),
        ("reference f64", "reference", {}, "float64", [1, 2, 4, 8, 16, 32]),
        ("rattle f32", "rattle", {}, "float32", [1, 2, 4, 8, 16, 32]),
    ])
    mode_masses: int = 10
    mode_segment: float = 0.05
    mode_numbers: list = field(default_factory=lambda: [0, 2])
    mode_rates: list = field(default_factory=lambda: [240, 960])
    mode_periods: int = 10
    mode_settings: list = field(default_factory=lambda: [
        ("reference", "reference", {}), ("dftl s=1", "dftl", {"damping": 1.0}), ("ftl (s=0)", "ftl", {}),
        ("pbd K=4", "pbd", {"iterations": 4}), ("pbd K=16", "pbd", {"iterations": 16}),
        ("rattle", "rattle", {}),
    ])
    map_dampings: list = field(default_factory=lambda: [0.0, 0.5, 0.8, 0.9, 1.0])
    map_dts: list = field(default_factory=lambda: [1 / 24, 1 / 240, 1e-3, 1e-4, 1e-5])
    map_particles: list = field(default_factory=lambda: [2, 4, 8, 16, 32, 64, 128, 256, 512, 1024])
    map_length: float = 0.2
    map_seconds: float = 1.0
    elastic_scenarios: list = field(default_factory=lambda: ["cantilever", "curly"])
    elastic_frames: int = 12  # 0.5 s at 24 fps
    elastic_substeps: list = field(default_factory=lambda: [8, 32, 128, 512, 2048])
    elastic_settings: list = field(default_factory=lambda: [
        ("elastic s=0", {"damping": 0.0}), ("elastic s=1 (default)", {})])
    elastic_strands: int = 8  # copies side by side: the elastic solver's wall time measures computation
    elastic_reference_fraction: float = 0.5  # the reference's step, as a fraction of its stability limit

    @classmethod
    def fast(cls, device: str = "cpu") -> StudyConfig:
        c = cls(device=device)
        c.chain_substeps = [10, 20, 40]
        c.chain_reference_substeps = 640
        c.chain_settings = [s for s in c.chain_settings if s[0] in (
            "dftl s=1 prior f64", "dftl s=1 posterior f64", "dftl s=0.8 f64", "pbd K=4 f64")]
        c.energy_seconds = 1.0
        c.groom_strands, c.groom_frames, c.groom_reference_substeps = 8, 6, 32
        c.groom_settings = [("dftl s=1 f32", "dftl", {"damping": 1.0}, "float32", [1, 8]),
                            ("pbd K=4 f32", "pbd", {"iterations": 4}, "float32", [1]),
                            ("reference f64", "reference", {}, "float64", [8])]
        c.mode_numbers, c.mode_rates, c.mode_periods = [0], [240], 4
        c.mode_settings = c.mode_settings[:2]
        c.map_dampings, c.map_dts, c.map_particles = [0.5, 1.0], [1 / 240, 1e-4], [4, 64]
        c.map_seconds = 0.5
        c.elastic_frames, c.elastic_substeps, c.elastic_strands = 6, [8, 32], 1
        return c


def _model(points, counts, precision, device):
    return Model.from_strands(points, counts, device=device, precision=precision)


def trajectory_error(x, ref, length):
    """max over frames of the RMS over particles of |x - ref|, / ``length``."""
    return float(np.sqrt(((x - ref) ** 2).sum(-1).mean(-1)).max() / length)


def max_stretch(positions, counts, rest):
    """Per frame: the largest relative segment stretch |l/l0 - 1| over all strands."""
    keep = np.ones(positions.shape[1] - 1, dtype=bool)
    keep[np.cumsum(counts)[:-1] - 1] = False
    lengths = np.linalg.norm(np.diff(positions, axis=1), axis=2)[:, keep]
    return np.abs(lengths / rest[keep] - 1).max(axis=1)


def fitted_slope(dts, errors):
    """Slope of log(error) against log(dt), least squares."""
    return float(np.polyfit(np.log(np.asarray(dts)), np.log(np.asarray(errors)), 1)[0])


def chain_energy(positions, velocities):
    """Per frame: energy (J/kg) of the free particles of one strand, ``|v|^2/2 + g_abs y``."""
    return (0.5 * (velocities[:, 1:] ** 2).sum(-1) + sc.GRAVITY * positions[:, 1:, 1]).sum(-1)


# -- 1. convergence on the falling chain ----------------------------------------------------------

def convergence(cfg: StudyConfig, log=print):
    pts = sc.horizontal_chain(cfg.chain_particles, cfg.chain_length)
    counts = [cfg.chain_particles]
    frame = cfg.chain_horizon / cfg.chain_frames

    def run(name, options, precision, substeps, clock=None):
        solver = make_solver(_model(pts, counts, precision, cfg.device), name, gravity=G, **options)
        return sc.record(solver, cfg.chain_frames, frame, substeps, clock=clock)[0]

    ref = run("reference", {}, "float64", cfg.chain_reference_substeps)
    ref_half = run("reference", {}, "float64", cfg.chain_reference_substeps // 2)
    reference_error = trajectory_error(ref_half, ref, cfg.chain_length)
    log(f"convergence: reference self-error {reference_error:.2e}")
    rows = []
    for label, name, options, precision in cfg.chain_settings:
        for substeps in cfg.chain_substeps:
            clock = []
            x = run(name, options, precision, substeps, clock)
            rows.append({
                "setting": label, "solver": name, "damping": options.get("damping", 0.0 if name == "ftl" else ""),
                "correction": options.get("correction", "prior" if name in ("dftl", "ftl") else ""),
                "iterations": options.get("iterations", ""), "precision": precision, "substeps": substeps,
                "dt": frame / substeps, "error": trajectory_error(x, ref, cfg.chain_length),
                "wall_s": float(np.sum(clock)),
            })
        errs = [r["error"] for r in rows if r["setting"] == label]
        log(f"convergence: {label:24s} slope {fitted_slope([frame / k for k in cfg.chain_substeps], errs):+.2f}")
    return rows, reference_error


# -- 2. energy against time ------------------------------------------------------------------------

def energy(cfg: StudyConfig, log=print):
    pts = sc.horizontal_chain(cfg.chain_particles, cfg.chain_length)
    frames = int(round(cfg.energy_seconds * 24))
    settings = [("reference", "reference", {}), ("dftl s=1 prior", "dftl", {"damping": 1.0}),
                ("dftl s=1 posterior", "dftl", {"damping": 1.0, "correction": "posterior"}),
                ("dftl s=0.9", "dftl", {"damping": 0.9}), ("dftl s=0.8", "dftl", {"damping": 0.8}),
                ("ftl (s=0)", "ftl", {}), ("pbd K=4", "pbd", {"iterations": 4}), ("rattle", "rattle", {})]
    rows = []
    scale = (cfg.chain_particles - 1) * sc.GRAVITY * cfg.chain_length
    for label, name, options in settings:
        solver = make_solver(_model(pts, [cfg.chain_particles], "float64", cfg.device), name, gravity=G, **options)
        x, v = sc.record(solver, frames, 1 / 24, cfg.energy_substeps)
        e = chain_energy(x, v)
        for f in range(frames + 1):
            rows.append({"setting": label, "time": f / 24, "energy": e[f], "relative": (e[f] - e[0]) / scale})
        log(f"energy: {label:20s} E(end) - E(0) = {(e[-1] - e[0]) / scale:+.3f} n g L")
    return rows


# -- 3. the groom: error, stretch, cost --------------------------------------------------------------

def groom(cfg: StudyConfig, log=print):
    pts, counts = sc.groom(cfg.groom_strands, cfg.groom_particles, cfg.groom_length)
    roots0 = pts[sc.strand_starts(counts)]

    def roots(t):
        return sc.head_roots(roots0, t)

    rest = np.zeros(len(pts))
    rest[1:] = np.linalg.norm(np.diff(pts, axis=0), axis=1)

    def run(name, options, precision, substeps):
        solver = make_solver(_model(pts, counts, precision, cfg.device), name, gravity=G, **options)
        clock = []
        x, _ = sc.record(solver, cfg.groom_frames, 1 / 24, substeps, roots=roots, clock=clock)
        # per-frame cost: the fastest frame (the first includes kernel compilation / graph capture;
        # the minimum is the least disturbed by other load on a shared machine)
        return x, float(np.min(clock)) * 24

    ref, _ = run("reference", {}, "float64", cfg.groom_reference_substeps)
    ref_half, _ = run("reference", {}, "float64", cfg.groom_reference_substeps // 2)
    reference_error = trajectory_error(ref_half, ref, cfg.groom_length)
    log(f"groom: {len(counts)} strands x {cfg.groom_particles}, reference self-error {reference_error:.2e}")
    rows, stretch_rows = [], []
    todo = [(label, name, opts, prec, k) for label, name, opts, prec, subs in cfg.groom_settings for k in subs]
    for preset, p in QUALITY_PRESETS.items():
        opts = {k: p[k] for k in ("damping", "correction") if k in p}
        todo.append((f"preset {preset}", p["solver"], opts, p["precision"], p["substeps"]))
    for label, name, options, precision, substeps in todo:
        x, seconds_per_second = run(name, options, precision, substeps)
        stretch = max_stretch(x, counts, rest[1:])
        rows.append({
            "setting": label, "solver": name, "damping": options.get("damping", ""),
            "iterations": options.get("iterations", ""), "precision": precision, "substeps": substeps,
            "dt": 1 / 24 / substeps, "error": trajectory_error(x, ref, cfg.groom_length),
            "max_stretch": float(stretch.max()), "wall_s_per_s": seconds_per_second,
            "particles": int(np.sum(counts)),
        })
        for f, value in enumerate(stretch):
            stretch_rows.append({"setting": label, "substeps": substeps, "time": f / 24, "max_stretch": value})
        r = rows[-1]
        log(f"groom: {label:24s} x{substeps:<3d} error {r['error']:.3e} stretch {r['max_stretch']:.1e} "
            f"cost {seconds_per_second:.3g} s/s")
    return rows, stretch_rows, reference_error


# -- 4. hanging-chain modes: period and damping ------------------------------------------------------

def _crossings(signal, dt):
    i = np.flatnonzero((signal[:-1] < 0) & (signal[1:] >= 0))
    return (i - signal[i] / (signal[i + 1] - signal[i])) * dt


def modes(cfg: StudyConfig, log=print):
    omega, shapes = sc.hanging_chain_modes(cfg.mode_masses, cfg.mode_segment)
    length = cfg.mode_masses * cfg.mode_segment
    amplitude = 1e-3 * length
    rows, traces = [], []
    for mode in cfg.mode_numbers:
        period = 2 * np.pi / omega[mode]
        pts = sc.hanging_chain_in_mode(cfg.mode_masses, cfg.mode_segment, shapes[:, mode], amplitude)
        for rate in cfg.mode_rates:
            steps = int(np.ceil(cfg.mode_periods * period * rate))
            for label, name, options in cfg.mode_settings:
                solver = make_solver(_model(pts, [cfg.mode_masses + 1], "float64", cfg.device), name, gravity=G,
                                     **options)
                x, _ = sc.record(solver, steps, 1 / rate, 1)
                modal = x[:, 1:, 0] @ shapes[:, mode]
                crossings = _crossings(modal, 1 / rate)
                measured = (crossings[-1] - crossings[0]) / (len(crossings) - 1) if len(crossings) >= 2 else np.nan
                per = int(np.ceil(period * rate))
                first, last = np.abs(modal[:per]).max(), np.abs(modal[-per:]).max()
                decay = (last / first) ** (1.0 / max(cfg.mode_periods - 1, 1))
                rows.append({"mode": mode + 1, "rate": rate, "setting": label, "period_exact": period,
                             "period": measured, "period_error": measured / period - 1,
                             "amplitude_per_period": decay})
                if rate == cfg.mode_rates[0]:
                    for k in range(0, len(modal), max(1, len(modal) // 400)):
                        traces.append({"mode": mode + 1, "setting": label, "time": k / rate,
                                       "modal": modal[k] / amplitude})
                log(f"modes: mode {mode + 1} at {rate}/s {label:12s} period error {measured / period - 1:+.2e} "
                    f"amplitude kept per period {decay:.4f}")
    return rows, traces


# -- 5. stability map ------------------------------------------------------------------------------

def stability(cfg: StudyConfig, log=print):
    ns = list(cfg.map_particles)
    pts = np.concatenate([sc.horizontal_chain(n, cfg.map_length) + [0.0, 0.0, 0.01 * i] for i, n in enumerate(ns)])
    frames = 24
    rows = []
    for dt in cfg.map_dts:
        for damping in cfg.map_dampings:
            model = _model(pts, ns, "float32", cfg.device)
            solver = make_solver(model, "dftl", damping=damping, gravity=G)
            state = solver.state()
            monitor = EnergyMonitor(solver, f"s={damping} dt={dt:g}", state)
            frame = cfg.map_seconds / frames
            substeps = max(1, int(round(frame / dt)))
            start = time.perf_counter()
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                sc.record(solver, frames, frame, substeps, state=state, monitor=monitor)
            order = model.layout.strand_order
            unstable = np.empty(len(ns), dtype=bool)
            ratio = np.empty(len(ns))
            unstable[order] = monitor.unstable
            ratio[order] = monitor.worst_ratio
            for n, u, r in zip(ns, unstable, ratio):
                segment = cfg.map_length / (n - 1)
                rows.append({"damping": damping, "dt": frame / substeps, "particles": n, "unstable": bool(u),
                             "worst_ratio": float(r), "dt_over_segment_time": frame / substeps / np.sqrt(segment / sc.GRAVITY)})
            log(f"stability: dt={dt:.2g} s={damping}: " + "".join("X" if u else "." for u in unstable)
                + f"  ({time.perf_counter() - start:.1f} s)")
    return rows


# -- 6. elastic strands against the elastic reference ----------------------------------------------

def _elastic_scenario(name: str):
    """(rest points, elastic material, roots(t) factory or None, description) of a scenario."""
    lb = (HAIR_E * np.pi * sc.HAIR_RADIUS ** 4 / 4 / (HAIR_DENSITY * np.pi * sc.HAIR_RADIUS ** 2 * sc.GRAVITY)) ** (1 / 3)
    if name == "cantilever":
        return (sc.hair_cantilever(lb), {"inverse_statics": False}, None,
                f"a straight strand L = l_b = {lb * 100:.2f} cm released horizontal, root held")
    if name == "curly":
        return (sc.hair_helix(), {}, sc.shaken_roots,
                "a styled helix (0.2 m, 2 turns of 1.5 cm radius; inverse statics: it hangs as authored), "
                "root shaken 2 cm at 2 Hz")
    raise ValueError(f"unknown elastic scenario {name!r}; choose cantilever or curly")


def elastic(cfg: StudyConfig, log=print):
    """The elastic solver against the elastic reference: (rows per setting and substeps, rows per
    scenario for the reference: its substeps, self error and cost)."""
    frame = 1 / 24
    rows, references = [], []
    for name in cfg.elastic_scenarios:
        rest, material, roots_of, description = _elastic_scenario(name)
        material = dict(radius=sc.HAIR_RADIUS, **material)
        n = rest.shape[0]
        length = float(np.linalg.norm(np.diff(rest, axis=0), axis=1).sum())
        copies = cfg.elastic_strands
        pts = np.concatenate([rest + [0.0, 0.0, 0.05 * i] for i in range(copies)])
        counts = [n] * copies
        roots = roots_of(pts[sc.strand_starts(counts)]) if roots_of else None
        one_root = roots_of(rest[:1]) if roots_of else None

        def reference(substeps, clock=None):
            solver = make_solver(_model(rest, [n], "float64", cfg.device), "reference", gravity=G, elastic=material)
            return sc.record(solver, cfg.elastic_frames, frame, substeps, roots=one_root, clock=clock)[0], solver

        probe = make_solver(_model(rest, [n], "float64", cfg.device), "reference", gravity=G, elastic=material)
        k = int(np.ceil(frame / (cfg.elastic_reference_fraction * probe.elastic.step_limit)))
        clock = []
        truth, _ = reference(k, clock)
        finer, _ = reference(2 * k)
        references.append({
            "scenario": name, "description": description, "length": length, "particles": n,
            "seconds": cfg.elastic_frames * frame, "substeps": k, "dt": frame / k,
            "step_limit": probe.elastic.step_limit, "self_error": trajectory_error(truth, finer, length),
            "wall_s_per_s": float(np.min(clock)) * 24, "ns_per_particle_step": float(np.min(clock)) / (k * n) * 1e9})
        log(f"elastic: {name}: reference {k} substeps (dt {frame / k:.2e} s, limit "
            f"{probe.elastic.step_limit:.2e} s), self-error {references[-1]['self_error']:.1e}")
        seg = np.linalg.norm(np.diff(pts, axis=0), axis=1)
        for label, options in cfg.elastic_settings:
            for substeps in cfg.elastic_substeps:
                solver = make_solver(_model(pts, counts, "float64", cfg.device), "elastic", gravity=G, **material,
                                     **options)
                clock = []
                x, _ = sc.record(solver, cfg.elastic_frames, frame, substeps, roots=roots, clock=clock)
                error = max(trajectory_error(x[:, i * n:(i + 1) * n] - [0.0, 0.0, 0.05 * i], truth, length)
                            for i in range(copies))
                rows.append({
                    "scenario": name, "setting": label, "damping": options.get("damping", 0.0),
                    "substeps": substeps, "dt": frame / substeps, "error": error,
                    "max_stretch": float(max_stretch(x, counts, seg).max()),
                    "wall_s_per_s": float(np.min(clock)) * 24,
                    "ns_per_particle_step": float(np.min(clock)) / (substeps * n * copies) * 1e9,
                })
                log(f"elastic: {name} {label:22s} x{substeps:<4d} error {error:.3e} "
                    f"cost {rows[-1]['ns_per_particle_step']:.3g} ns/particle-step")
    return rows, references


def run_study(cfg: StudyConfig, log=print) -> dict:
    """Run every sweep; returns the rows by sweep name plus timing."""
    started = time.perf_counter()
    out = {}
    out["convergence"], out["chain_reference_error"] = convergence(cfg, log)
    out["energy"] = energy(cfg, log)
    out["groom"], out["stretch"], out["groom_reference_error"] = groom(cfg, log)
    out["modes"], out["mode_traces"] = modes(cfg, log)
    out["stability"] = stability(cfg, log)
    out["elastic"], out["elastic_reference"] = elastic(cfg, log)
    out["seconds"] = time.perf_counter() - started
    return out
