#!/usr/bin/env python3
"""The elastic solver against physics: the numbers of docs/elastic.md.

Horizontal cantilevers of 80 um human hair (32 segments) against the large-deflection elastica,
their sag at 2, 8 and 32 substeps per 24 fps frame, the first bending frequency of a short
cantilever against the Euler-Bernoulli value, a curly strand without gravity, a styled strand
under gravity, the total energy of a swinging strand at 1 to 128 substeps, written velocities
against the central difference of written positions, and the CPU cost against DFTL.

    python scripts/elastic_study.py --out docs/elastic     # writes study.md and study.json
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import time
from datetime import date
from pathlib import Path

import numpy as np
import warp as wp

import dftl_warp as dw

R = 40e-6  # 80 um hair
N = 32
FPS = 24.0
G0 = 9.81


def material():
    from dftl_warp.solvers.elastic import HAIR_DENSITY, HAIR_E

    ei = HAIR_E * np.pi * R ** 4 / 4
    w = HAIR_DENSITY * np.pi * R ** 2 * G0
    return HAIR_E, HAIR_DENSITY, ei, w, (ei / w) ** (1.0 / 3.0)


def elastica(L, s_eval, ei, w):
    """(x, y) of a horizontal cantilever under its own weight: EI th'' = -w (L - s) cos th."""
    from scipy.integrate import cumulative_trapezoid, solve_bvp

    s = np.linspace(0, L, 401)
    guess = np.zeros((2, s.size))
    for frac in np.linspace(0.1, 1.0, 10):  # continuation in the load
        sol = solve_bvp(lambda s, y, q=w * frac: np.vstack([y[1], -q * (L - s) * np.cos(y[0]) / ei]),
                        lambda a, b: np.array([a[0], b[1]]), s, guess, tol=1e-10, max_nodes=100000)
        guess = sol.sol(s)
    sf = np.linspace(0, L, 20001)
    th = sol.sol(sf)[0]
    xs = cumulative_trapezoid(np.cos(th), sf, initial=0.0)
    ys = -np.abs(cumulative_trapezoid(np.sin(th), sf, initial=0.0))
    return np.interp(s_eval, sf, xs), np.interp(s_eval, sf, ys)


def straight(lengths):
    rest = np.zeros((len(lengths), N + 1, 3))
    for k, L in enumerate(lengths):
        rest[k, :, 0] = np.linspace(0, L, N + 1)
    return rest


def helix(L, turns, radius):
    s = np.linspace(0, L, N + 1)
    c = L / np.sqrt((2 * np.pi * turns * radius) ** 2 + L ** 2)
    ang = 2 * np.pi * turns * s / L
    pts = np.stack([radius * (np.cos(ang) - 1), -s * c, radius * np.sin(ang)], axis=-1)
    seg = np.diff(pts, axis=0)
    seg *= (L / N) / np.linalg.norm(seg, axis=1, keepdims=True)
    return np.concatenate([pts[:1], pts[:1] + np.cumsum(seg, axis=0)])[None]


def setup(rest, solver="elastic", device="cpu", precision="float64", **options):
    model = dw.Model.from_strands(rest.reshape(-1, 3), [rest.shape[1]] * rest.shape[0], precision=precision,
                                  device=device)
    if solver == "elastic":
        options.setdefault("radius", R)
    s = dw.make_solver(model, solver, **options)
    return model, s, s.state(), model.control()


def points(model, state, shape):
    return model.points_from_device(state.positions).reshape(shape)


def run(solver, state, control, substeps, frames, record=None):
    for _ in range(frames):
        solver.advance(state, control, 1.0 / (FPS * substeps), substeps)
        if record is not None:
            record()


def statics(ratios, lb, ei, w):
    lengths = np.array(ratios) * lb
    rows, tips = [], {}
    for sub in (2, 8, 32):
        model, solver, state, control = setup(straight(lengths), inverse_statics=False, drag=20.0)
        run(solver, state, control, sub, int(4 * FPS))  # drag only speeds settling; the equilibrium is exact
        x = points(model, state, (len(lengths), N + 1, 3))
        tips[sub] = x[:, -1, 1] / lengths
        for k, L in enumerate(lengths):
            xe, ye = elastica(L, np.linspace(0, L, N + 1), ei, w)
            err = np.linalg.norm(np.c_[xe, ye] - x[k, :, :2], axis=1).max() / L
            rows.append({"L/l_b": ratios[k], "substeps": sub, "error/L": float(err), "sag/L": float(-tips[sub][k])})
    spread = np.ptp(np.array([tips[s] for s in (2, 8, 32)]), axis=0)
    return rows, {r: float(v) for r, v in zip(ratios, spread)}


def frequency(lb, ei, density):
    """First bending frequency of L = l_b/2 released straight, from the tip's upward crossings of
    its mean height."""
    L = lb / 2
    omega1 = 1.8751 ** 2 * np.sqrt(ei / (density * np.pi * R ** 2 * L ** 4))
    out = {"omega1 (rad/s)": float(omega1)}
    for sub in (512, 8):
        model, solver, state, control = setup(straight([L]), inverse_statics=False)
        dt = 1.0 / (FPS * sub)
        tip = []
        for _ in range(int(round(0.25 / dt))):
            solver.step(state, state, control, dt)
            tip.append(points(model, state, (N + 1, 3))[-1, 1])
        tip = np.array(tip) - np.mean(tip)
        ups = np.flatnonzero((tip[:-1] < 0) & (tip[1:] >= 0))
        if len(ups) >= 3:
            t = (ups + tip[ups] / (tip[ups] - tip[ups + 1])) * dt  # linear crossing times
            omega = 2 * np.pi / np.mean(np.diff(t))
            out[f"{sub} substeps"] = float(omega / omega1 - 1)
        else:
            out[f"{sub} substeps"] = None  # damped out before two periods
    return out


def stillness():
    rest = helix(0.2, 3.0, 0.01)
    model, solver, state, control = setup(rest, gravity=(0.0, 0.0, 0.0))
    run(solver, state, control, 8, int(10 * FPS))
    curly = float(np.linalg.norm(points(model, state, rest.shape) - rest, axis=-1).max() / 0.2)
    rest = helix(0.2, 2.0, 0.015)
    model, solver, state, control = setup(rest)
    run(solver, state, control, 8, int(3 * FPS))
    v = model.points_from_device(state.velocities, relative=False)
    out = {"curly, no gravity, 10 s: max displacement / L": curly,
           "styled, gravity, after 3 s: max speed (L/s)": float(np.linalg.norm(v, axis=1).max() / 0.2)}
    for compute in ("float64", "float32"):
        model, solver, state, control = setup(rest, precision="float32", compute_precision=compute)
        run(solver, state, control, 8, int(3 * FPS))
        moved = np.linalg.norm(points(model, state, rest.shape) - rest, axis=-1).max() / 0.2
        out[f"styled, gravity, float32 model, {compute} arithmetic, 3 s: max displacement / L"] = float(moved)
    return out


def energy(lb):
    out = {}
    for sub in (1, 2, 8, 32, 128):
        model, solver, state, control = setup(straight([lb]), inverse_statics=False)
        e = [solver.energy(state)]
        run(solver, state, control, sub, 48, lambda: e.append(solver.energy(state)))
        e = np.array(e)
        out[sub] = {"max rise / E0": float(np.max(e - np.minimum.accumulate(e)) / abs(e[0])),
                    "E(2 s) / E0": float(e[-1] / e[0])}
    return out


def velocities(lb):
    """p1/p99 over points and frames of |v| / |cd|, cd the central difference of the written
    positions, where a point moves (|cd| at least 10% of the largest over the run: near turning
    points both vanish and their ratio says nothing)."""
    out = {}
    cases = (("L = 4 l_b released horizontal (slow swing)", 4 * lb, 0.0),
             ("L = l_b released straight, root shaken 1 cm at 1 Hz on the C1 path (its 8 Hz bending rings)", lb, 0.01),
             ("L = l_b released horizontal (8 Hz bending: 3 frames a period)", lb, 0.0))
    for name, L, amplitude in cases:
        model, solver, state, control = setup(straight([L]), inverse_statics=False)
        xs, vs = [], []
        for f in range(48):
            if amplitude:
                root = np.array([[0.0, amplitude * np.sin(2 * np.pi * (f + 1) / FPS), 0.0]])
                start = np.array([[0.0, amplitude * np.sin(2 * np.pi * f / FPS), 0.0]])
                # the root's velocity at the frame's ends: the C1 root path inside the frame
                rate = [np.array([[0.0, amplitude * 2 * np.pi * np.cos(2 * np.pi * g / FPS), 0.0]]) for g in (f, f + 1)]
                control.set_root_targets(start, root, velocity_start=rate[0], velocity_end=rate[1],
                                         frame_duration=1.0 / FPS)
            solver.advance(state, control, 1.0 / (FPS * 8), 8)
            xs.append(points(model, state, (N + 1, 3)))
            vs.append(model.points_from_device(state.velocities, relative=False).reshape(N + 1, 3))
        x, v = np.array(xs), np.array(vs)
        cd = np.linalg.norm((x[2:] - x[:-2]) * FPS / 2, axis=-1)
        speed = np.linalg.norm(v[1:-1], axis=-1)
        moving = cd >= 0.1 * cd.max()
        ratio = speed[moving] / cd[moving]
        out[name] = [float(np.percentile(ratio, 1)), float(np.percentile(ratio, 99))]
    return out


def cost():
    """CPU time per particle-step, 300 curly strands x 33 vertices, 8 substeps, float64 model."""
    rest = np.concatenate([helix(0.2, 3.0, 0.01)] * 300)
    rest += np.repeat(np.arange(300)[:, None, None] * np.array([0.05, 0.0, 0.0]), N + 1, axis=1)
    out = {}
    for solver_name in ("dftl", "elastic"):
        model, solver, state, control = setup(rest, solver=solver_name)
        run(solver, state, control, 8, 1)  # compile
        t = time.perf_counter()
        run(solver, state, control, 8, 6)
        out[solver_name] = (time.perf_counter() - t) / (6 * 8 * rest.shape[0] * rest.shape[1]) * 1e9
    return {"ns per particle-step": out}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="docs/elastic")
    args = ap.parse_args()
    wp.config.quiet = True
    wp.init()
    E, rho, ei, w, lb = material()
    res = {"date": str(date.today()), "machine": f"{os.cpu_count()}-core CPU VM ({platform.machine()}), CPU device",
           "material": {"E (Pa)": E, "density (kg/m^3)": rho, "radius (m)": R, "l_b (m)": lb}}
    res["statics"], res["sag spread over 2/8/32 substeps (/L)"] = statics((0.5, 1.0, 2.0, 4.0), lb, ei, w)
    res["frequency (omega/omega1 - 1)"] = frequency(lb, ei, rho)
    res["stillness"] = stillness()
    res["energy, L = l_b released horizontal, 2 s"] = energy(lb)
    res["velocity / central difference, 8 substeps, p1 and p99"] = velocities(lb)
    res.update(cost())
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "study.json").write_text(json.dumps(res, indent=1))
    md = [f"Command: `python scripts/elastic_study.py --out {args.out}`; {res['machine']}; {res['date']}.", "",
          f"80 um hair: E = {E:.3g} Pa, density {rho:g} kg/m^3, bending length l_b = {100 * lb:.2f} cm; "
          f"{N} segments; float64.", "",
          "| L / l_b | substeps | max distance to the elastica / L | tip sag / L |", "|---:|---:|---:|---:|"]
    md += [f"| {r['L/l_b']:g} | {r['substeps']} | {r['error/L']:.5f} | {r['sag/L']:.4f} |" for r in res["statics"]]
    md += ["", "Sag spread over 2, 8 and 32 substeps (/L): " + ", ".join(
        f"L = {k:g} l_b: {v:.1e}" for k, v in res["sag spread over 2/8/32 substeps (/L)"].items()), ""]
    f = res["frequency (omega/omega1 - 1)"]
    md += [f"First bending frequency of L = l_b/2 (omega1 = {f['omega1 (rad/s)']:.1f} rad/s): "
           + ", ".join(f"{k}: {v:+.3%}" if v is not None else f"{k}: damped out before two periods"
                       for k, v in f.items() if k != "omega1 (rad/s)"), ""]
    md += [f"- {k}: {v:.2e}" for k, v in res["stillness"].items()] + [""]
    md += ["| substeps per frame | max energy rise / E0 | E(2 s) / E0 |", "|---:|---:|---:|"]
    md += [f"| {k} | {v['max rise / E0']:.1e} | {v['E(2 s) / E0']:.3f} |"
           for k, v in res["energy, L = l_b released horizontal, 2 s"].items()] + [""]
    md += ["| motion (8 substeps) | velocity / central difference, p1 | p99 |", "|---|---:|---:|"]
    md += [f"| {k} | {v[0]:.3f} | {v[1]:.3f} |" for k, v in res["velocity / central difference, 8 substeps, p1 and p99"].items()]
    c = res["ns per particle-step"]
    md += ["", f"CPU cost, 300 curly strands x 33 vertices, 8 substeps: DFTL {c['dftl']:.1f} ns, elastic "
               f"{c['elastic']:.0f} ns per particle-step ({c['elastic'] / c['dftl']:.0f}x)."]
    (out / "study.md").write_text("\n".join(md) + "\n")
    print("\n".join(md))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
