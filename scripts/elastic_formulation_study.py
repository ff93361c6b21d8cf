#!/usr/bin/env python3
"""Candidate "L" for a cheaper elastic step (issue 17): lagged tensions with a constant bending matrix.

A numpy/scipy study on the CPU (no Warp kernels) of the formulation docs/elastic.md "Cost" names as
the way to the 2x target, measured against the elastic solver's acceptance lines. One step of
length h (s) of a strand of N + 1 particles (0 the kinematic root, a kinematic clamp ghost behind
it; masses m_i, bending weights W_j, the discrete curvature D and the energy are the elastic
solver's own, from ``dftl_warp.solvers.elastic_rest.RodGroup``; straight rest shapes, b = 0):

1. velocities: ``(M (1 + h drag) + h^2 K [+ h^2 K_T]) v* = M v + h (M g - K x + J^T lam)``, K = D^T W D
   the constant scalar pentadiagonal bending matrix (the same for x, y and z), lam the segment
   multipliers carried from the last step (tension T = -lam, N), K_T the isotropic string
   stiffness of the carried tensions, sum_i max(T_i, 0) / l_i (graph Laplacian of segment i);
2. p = x + h v*, follow the leader to exact lengths, c = x_new - p;
3. multipliers: the KKT step would have added the impulse h J^T dlam that cancels the length rate
   of v*: J S^-1 J^T dlam h = J c / h (S the step's matrix; J c = t . (c_i - c_{i-1}) is the
   linearised length defect of p, the same for any projection). With S ~ M:
   ``(J M^-1 J^T) dlam = J c / h^2`` -- a scalar tridiagonal solve per strand ("tridiagonal"); its
   Jacobi approximation dlam_i = J c_i / (h^2 (1/m_{i-1} + 1/m_i)) ("local", 1/m_0 = 0); the dense
   consistent J S^-1 J^T ("exact", N pentadiagonal solves a step) as a diagnostic of the lag alone;
4. velocity v = (x_new - x) / h - s c_{i+1} / h (DFTL's correction; s = 0 in the forms measured, s = 1
   in one row: the correction's length rate feeds the tension update).

The report (docs/elastic/formulation-study.md) measures statics against the elastica, settling,
the first bending frequency, the energy of a swinging strand and the memory traffic by count.

At a fixed point (v = 0, c = 0) step 1 reads M g - K x + J^T lam = 0 for any h: the exact discrete
equilibrium, the same as the elastic solver's.

    python scripts/elastic_formulation_study.py                          # prints the report
    python scripts/elastic_formulation_study.py --current --out docs/elastic
        # also writes formulation-study-output.md and formulation-study.json there; --current adds the
        # present elastic solver's energy on the long swing (its Warp kernel on the CPU)
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np
from scipy.linalg import cho_solve_banded, cholesky_banded, solve_banded, solveh_banded

sys.path.insert(0, str(Path(__file__).resolve().parent))
from elastic_study import elastica  # noqa: E402  (the large-deflection elastica, scipy solve_bvp)

from dftl_warp.solvers.elastic import HAIR_DENSITY, HAIR_E  # noqa: E402
from dftl_warp.solvers.elastic_rest import RodGroup  # noqa: E402

R = 40e-6            # 80 um hair, m
N = 32               # segments
FPS = 24.0
G = np.array([0.0, -9.81, 0.0])
EI = HAIR_E * np.pi * R ** 4 / 4
WL = HAIR_DENSITY * np.pi * R ** 2 * 9.81
LB = (EI / WL) ** (1.0 / 3.0)

#: the forms measured: tension update, K_T in the matrix, s (DFTL's correction), rate (None: the whole
#: length defect feeds the update; "velocity" / "inertia": the share of h v^n / h S^-1 M v^n removed)
FORMS = {
    "L0 local": dict(update="local", string=False, s=0.0),
    "L1 tridiagonal": dict(update="tridiagonal", string=False, s=0.0),
    "L2 tridiagonal + K_T": dict(update="tridiagonal", string=True, s=0.0),
    "Lx dense J S^-1 J^T (diagnostic)": dict(update="exact", string=False, s=0.0),
}
#: further tension updates, measured on the long swing only
EXTRA = {
    "L1, s = 1": dict(update="tridiagonal", string=False, s=1.0),
    "L1, rate = velocity": dict(update="tridiagonal", string=False, s=0.0, rate="velocity"),
    "L1, rate = inertia": dict(update="tridiagonal", string=False, s=0.0, rate="inertia"),
    "Lx, rate = inertia, s = 1": dict(update="exact", string=False, s=1.0, rate="inertia"),
}


class Strand:
    """One strand of 80 um hair, straight at rest along ``direction`` from the origin, length L (m);
    ``drag`` (1/s) toward still air, implicit; ``update``, ``string``, ``s`` and ``rate`` as in FORMS."""

    def __init__(self, L, direction=(1.0, 0.0, 0.0), *, update="tridiagonal", string=False, drag=0.0, s=0.0, rate=None):
        d = np.asarray(direction, float) / np.linalg.norm(direction)
        rest = np.linspace(0, L, N + 1)[:, None] * d
        self.rod = RodGroup(rest[None], R, E=HAIR_E, G=0.89e10, rho=HAIR_DENSITY, gravity=G,
                            inverse_statics=False)
        self.L, self.update, self.string, self.drag, self.s, self.rate = L, update, string, drag, s, rate
        self.l = self.rod.l[0, 1:N + 1]                  # segment lengths l_1..l_N
        self.m = self.rod.m[0, 1:]                      # free masses m_1..m_N
        self.ghost = self.rod.ghost[0]
        # dense D on [ghost, x_0, ..., x_N] (N x (N+2)), K = D^T W D on the free particles
        Dfull = np.zeros((N, N + 2))
        lg = np.r_[self.rod.l[0, 0], self.l]           # l_0 (ghost), l_1..l_N
        for j in range(N):                              # (Dx)_j = -(x_j - x_{j-1})/l_j + (x_{j+1} - x_j)/l_{j+1}
            Dfull[j, j + 1] -= 1 / lg[j]
            Dfull[j, j] += 1 / lg[j]
            Dfull[j, j + 2] += 1 / lg[j + 1]
            Dfull[j, j + 1] -= 1 / lg[j + 1]
        self.Dfull, self.W = Dfull, self.rod.W[0]
        Kfull = Dfull.T @ (self.W[:, None] * Dfull)
        self.K = Kfull[2:, 2:]
        self.x = np.vstack([rest])
        self.v = np.zeros_like(self.x)
        self.lam = np.zeros(N)                          # carried multipliers (T = -lam)
        self.factor_h = None

    # -- pieces of the step
    def bending_force(self, x):
        """-dE_b/dx on the free particles (N), x the root and free particles (m)."""
        return -(self.Dfull.T @ (self.W[:, None] * (self.Dfull @ np.vstack([self.ghost, x]))))[2:]

    def tangents(self, x):
        return (x[1:] - x[:-1]) / self.l[:, None]

    def constraint_force(self, lam, t):
        f = lam[:, None] * t                            # (J^T lam)_k = lam_k t_k - lam_{k+1} t_{k+1}
        f[:-1] -= lam[1:, None] * t[1:]
        return f

    def matrix_bands(self, h, t):
        """Upper bands (3, N) of M (1 + h drag) + h^2 K [+ h^2 K_T]."""
        A = np.diag(self.m * (1 + h * self.drag)) + h * h * self.K
        if self.string:
            k = np.maximum(-self.lam, 0.0) / self.l     # tension / length per segment
            A[np.arange(N), np.arange(N)] += h * h * (k + np.r_[k[1:], 0.0])
            A[np.arange(N - 1), np.arange(1, N)] -= h * h * k[1:]
            A[np.arange(1, N), np.arange(N - 1)] -= h * h * k[1:]
        ab = np.zeros((3, N))
        ab[2] = np.diag(A)
        ab[1, 1:] = np.diag(A, 1)
        ab[0, 2:] = np.diag(A, 2)
        return ab

    def step(self, h):
        x, v = self.x[1:], self.v[1:]
        t = self.tangents(self.x)
        rhs = self.m[:, None] * v + h * (self.m[:, None] * G + self.bending_force(self.x)
                                         + self.constraint_force(self.lam, t))
        if self.string:                                  # K_T: the matrix changes every step
            ab = self.matrix_bands(h, t)
            solve = lambda b: solveh_banded(ab, b)  # noqa: E731
        else:                                            # constant matrix: factored once per h
            if self.factor_h != h:
                self.factor, self.factor_h = cholesky_banded(self.matrix_bands(h, t)), h
            solve = lambda b: cho_solve_banded((self.factor, False), b)  # noqa: E731
        vs = solve(rhs)
        p = np.vstack([self.x[:1], x + h * vs])
        xn = p.copy()
        for i in range(1, N + 1):                        # follow the leader
            d = p[i] - xn[i - 1]
            xn[i] = xn[i - 1] + self.l[i - 1] * d / np.linalg.norm(d)
        c = xn - p
        tn = self.tangents(xn)
        jc = np.sum(tn * (c[1:] - c[:-1]), axis=1)      # linearised length defect of p per segment
        if self.rate is not None:                        # keep only the forces' share of the defect
            w = v if self.rate == "velocity" else solve(self.m[:, None] * v)   # v, or S^-1 M v
            w = np.vstack([np.zeros(3), w])
            jc += h * np.sum(tn * (w[1:] - w[:-1]), axis=1)
        inv_m = 1.0 / self.m
        diag = inv_m + np.r_[0.0, inv_m[:-1]]            # 1/m_i + 1/m_{i-1}, 1/m_0 = 0
        if self.update == "local":
            dlam = jc / (h * h * diag)
        elif self.update == "exact":                     # (J S^-1 J^T) dlam = J c / h^2, dense (diagnostic)
            Jn = np.zeros((N, N, 3))
            Jn[np.arange(N), np.arange(N)] = tn
            Jn[np.arange(1, N), np.arange(N - 1)] = -tn[1:]
            SJ = np.stack([solve(Jn[k]) for k in range(N)])                    # rows of (S^-1 J^T)^T
            dlam = np.linalg.solve(Jn.reshape(N, 3 * N) @ SJ.reshape(N, 3 * N).T, jc / (h * h))
        else:                                            # (J M^-1 J^T) dlam = J c / h^2, tridiagonal
            off = -np.sum(tn[1:] * tn[:-1], axis=1) * inv_m[:-1]
            ab = np.zeros((3, N))
            ab[0, 1:], ab[1], ab[2, :-1] = off, diag, off
            dlam = solve_banded((1, 1), ab, jc / (h * h))
        self.lam = self.lam + dlam
        vn = (xn - self.x) / h
        vn[:-1] -= self.s * c[1:] / h                    # DFTL: particle i loses s c_{i+1} / h
        vn[0] = 0.0
        self.x, self.v = xn, vn

    # -- measures
    def energy(self):
        return float(self.rod.energy(self.x[None], self.v[None], np.broadcast_to(np.eye(3), (1, N, 3, 3)),
                                     self.ghost[None], G)[0])

    def speed(self):
        return float(np.linalg.norm(self.v, axis=1).max())

    def residual(self):
        """max |M g - K x + J^T lam| over the free particles (N): zero at the step's fixed point."""
        return float(np.linalg.norm(self.m[:, None] * G + self.bending_force(self.x)
                                    + self.constraint_force(self.lam, self.tangents(self.x)), axis=1).max())


def frame(strand, substeps, record=None):
    """One 24 fps frame in ``substeps`` steps; ``record()`` after each step."""
    h = 1.0 / (FPS * substeps)
    for _ in range(substeps):
        strand.step(h)
        if record is not None:
            record()


# ------------------------------------------------------------------------------------ measurements
def statics(form):
    """Cantilevers L = 0.5 ... 4 l_b released horizontal, drag 20/s, 4 s, at 2, 8 and 32 substeps."""
    rows, tips = [], {}
    for sub in (2, 8, 32):
        tips[sub] = []
        for ratio in (0.5, 1.0, 2.0, 4.0):
            L = ratio * LB
            st = Strand(L, drag=20.0, **form)
            for _ in range(int(4 * FPS)):
                frame(st, sub)
            xe, ye = elastica(L, np.linspace(0, L, N + 1), EI, WL)
            err = np.linalg.norm(np.c_[xe, ye] - st.x[:, :2], axis=1).max() / L
            tips[sub].append(-st.x[-1, 1] / L)
            rows.append(dict(ratio=ratio, substeps=sub, error=float(err), sag=float(tips[sub][-1]),
                             speed=st.speed() / L, residual=st.residual() / (WL * L)))
    spread = np.ptp(np.array([tips[k] for k in (2, 8, 32)]), axis=0)
    return rows, [float(v) for v in spread]


def settling(form):
    """Cantilevers L = l_b and 4 l_b released horizontal, drag 20/s, 8 s: when the largest speed
    falls below 1e-3 L/s for good, and the largest speed over the last second (L/s)."""
    out = []
    for ratio in (1.0, 4.0):
        for sub in (1, 2, 8):
            st = Strand(ratio * LB, drag=20.0, **form)
            speed = []
            for _ in range(int(8 * FPS)):
                frame(st, sub)
                speed.append(st.speed() / st.L if np.isfinite(st.speed()) else np.inf)
            speed = np.array(speed)
            above = np.flatnonzero(~(speed < 1e-3))
            t = None if len(above) and above[-1] == len(speed) - 1 else (above[-1] + 1 if len(above) else 0) / FPS
            out.append(dict(ratio=ratio, substeps=sub, settled=t, last=float(speed[-int(FPS):].max())))
    return out


def hanging(form):
    """A strand of 4 l_b hanging straight down, started with zero tensions, no drag: the root
    segment's tension / the weight it carries after 1 frame and 2 s, and the largest speed (L/s)."""
    out = []
    for sub in (1, 2, 8):
        st = Strand(4 * LB, (0.0, -1.0, 0.0), **form)
        weight = st.m.sum() * 9.81
        frame(st, sub)
        first = -st.lam[0] / weight
        vmax = st.speed()
        for _ in range(int(2 * FPS) - 1):
            frame(st, sub)
            vmax = max(vmax, st.speed())
        out.append(dict(substeps=sub, first=float(first), end=float(-st.lam[0] / weight), vmax=vmax / st.L))
    return out


def frequency(form):
    """First bending frequency of L = l_b/2 released straight (omega / omega1 - 1), from the tip's
    upward crossings of its mean height over 0.25 s, at 512 and 8 substeps."""
    L = LB / 2
    omega1 = 1.8751 ** 2 * np.sqrt(EI / (HAIR_DENSITY * np.pi * R ** 2 * L ** 4))
    out = {}
    for sub in (512, 8):
        st = Strand(L, **form)
        tip = []
        frames = int(round(0.25 * FPS))
        with np.errstate(all="ignore"):                  # a blown-up run is a result, reported as n/a
            for _ in range(frames):
                frame(st, sub, lambda: tip.append(st.x[-1, 1]))
        tip = np.array(tip) - np.mean(tip)
        ups = np.flatnonzero((tip[:-1] < 0) & (tip[1:] >= 0))
        dt = 1.0 / (FPS * sub)
        if len(ups) >= 3 and np.all(np.isfinite(tip)):
            t = (ups + tip[ups] / (tip[ups] - tip[ups + 1])) * dt
            out[sub] = float(2 * np.pi / np.mean(np.diff(t)) / omega1 - 1)
        else:
            out[sub] = None
    return out


def energy(form, ratio, counts=(1, 2, 8, 32, 128)):
    """Largest rise of kinetic + gravitational + elastic energy over its running minimum / E0 and
    E(2 s) / E0, L = ratio l_b released horizontal, no drag."""
    out = {}
    for sub in counts:
        st = Strand(ratio * LB, **form)
        e = [st.energy()]
        with np.errstate(all="ignore"):
            for _ in range(48):
                frame(st, sub)
                e.append(st.energy())
        e = np.array(e)
        e = np.where(np.isfinite(e), e, np.inf)
        out[sub] = (float(np.max(e - np.minimum.accumulate(e)) / e[0]), float(e[-1] / e[0]))
    return out


def current_energy(ratio, counts=(1, 2, 8, 32, 128)):
    """The same energy measure for the present elastic solver (Warp kernel on the CPU)."""
    import warp as wp

    from elastic_study import run, setup, straight
    wp.config.quiet = True
    wp.init()
    out = {}
    for sub in counts:
        model, solver, state, control = setup(straight([ratio * LB]), inverse_statics=False)
        e = [solver.energy(state)]
        run(solver, state, control, sub, 48, lambda: e.append(solver.energy(state)))
        e = np.array(e)
        out[sub] = (float(np.max(e - np.minimum.accumulate(e)) / e[0]), float(e[-1] / e[0]))
    return out


#: words read + written per free particle per step, float32, by sweep (counted from the designs:
#: sweep 1 tip -> root builds the right-hand side and does the forward substitution, sweep 2 root -> tip
#: the back substitution fused with follow-the-leader and the tension update)
TRAFFIC = {
    "DFTL, prior form (docs/benchmarks.md)": {"x 3+3, v 3+3, c 3+3, rest length 1": 19},
    "elastic (present), straight / curved (kernels/solvers/elastic.py)": {
        "storage 38 (curved), arithmetic 73 (curved); straight strands skip the frame sweep (-21)": (90, 111)},
    "L0, constant matrix, local tension update, s = 0": {
        "sweep 1 reads x 3, v 3, T 1, mass 1, W 1, length 1, factor 3 (pivot, 2 multipliers)": 13,
        "sweep 1 writes the forward-substituted y 3": 3,
        "sweep 2 reads y 3, x 3, length 1, multipliers 2": 9,
        "sweep 2 writes x 3, v 3, T 1": 7},
    "L1, constant matrix, tridiagonal tension solve, s = 0": {
        "L0": 32, "Thomas forward pass in sweep 2 writes 2 (pivot, rhs), its back pass in the next sweep 1 reads 2": 4,
        "(T is then read and written once, as in L0)": 0},
    "L2, L1 + K_T (matrix refactored every step)": {
        "L1": 36, "bands k0 k1 k2 instead of the stored factor": 0,
        "factor written in sweep 1 (pivot and 2 multipliers: 3); sweep 2 reads the 2 multipliers as in L0": 3},
}


def traffic_rows():
    rows = []
    for name, parts in TRAFFIC.items():
        total = sum(v for v in parts.values() if not isinstance(v, tuple))
        if any(isinstance(v, tuple) for v in parts.values()):
            total = next(v for v in parts.values() if isinstance(v, tuple))
        rows.append((name, total, "; ".join(k for k in parts)))
    return rows


# ------------------------------------------------------------------------------------------ report
def fmt_t(t):
    return "not within 8 s" if t is None else f"{t:.2f} s"


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", help="folder for formulation-study.md and formulation-study.json")
    ap.add_argument("--current", action="store_true",
                    help="also measure the present elastic solver's energy on the long swing (Warp, CPU)")
    args = ap.parse_args()
    t0 = time.perf_counter()
    res = {"l_b (m)": LB, "forms": {}}
    for name, form in FORMS.items():
        r = res["forms"][name] = {}
        r["statics"], r["spread"] = statics(form)
        r["settling"] = settling(form)
        r["hanging"] = hanging(form)
        r["frequency"] = frequency(form)
        r["energy l_b"] = energy(form, 1.0)
        r["energy 4 l_b"] = energy(form, 4.0)
    res["extra"] = {name: energy(form, 4.0, (1, 2, 8, 32)) for name, form in EXTRA.items()}
    res["extra frequency"] = {name: frequency(form) for name, form in EXTRA.items() if name == "L1, s = 1"}
    res["extra energy l_b"] = {name: energy(form, 1.0, (32, 128)) for name, form in EXTRA.items()
                               if name == "L1, s = 1"}
    if args.current:
        res["current 4 l_b"] = current_energy(4.0)
    res["traffic"] = traffic_rows()
    res["seconds"] = time.perf_counter() - t0

    md = [f"80 um hair (E = {HAIR_E:.3g} Pa, density {HAIR_DENSITY:g} kg/m^3, r = 40 um), l_b = {100 * LB:.2f} cm, "
          f"{N} segments, float64, straight rest shapes (b = 0), root clamped by the ghost. Limits: statics within "
          "2% of L of the elastica and the sag at 2/8/32 substeps within 1% of L; frequency within 3%; energy never "
          "rising more than 1e-3 E0.", ""]
    forms = list(FORMS)
    md += ["### 1. Statics: horizontal cantilevers after 4 s (drag 20/s), max distance to the elastica / L", "",
           "| L / l_b | substeps | " + " | ".join(forms) + " |", "|---:|---:|" + "---:|" * len(forms)]
    n = len(res["forms"][forms[0]]["statics"])
    for k in range(n):
        r0 = res["forms"][forms[0]]["statics"][k]
        md.append(f"| {r0['ratio']:g} | {r0['substeps']} | " + " | ".join(
            f"{res['forms'][f]['statics'][k]['error']:.5f} ({res['forms'][f]['statics'][k]['speed']:.0e} L/s)"
            for f in forms) + " |")
    md += ["", "(in brackets: the largest speed at the end, L/s)", "",
           "| sag spread over 2/8/32 substeps / L | " + " | ".join(forms) + " |", "|---|" + "---:|" * len(forms)]
    for k, ratio in enumerate((0.5, 1.0, 2.0, 4.0)):
        md.append(f"| L = {ratio:g} l_b | " + " | ".join(f"{res['forms'][f]['spread'][k]:.1e}" for f in forms) + " |")
    md += ["", "### 2. Settling: released horizontal, drag 20/s, 8 s: time to stay below 1e-3 L/s (largest speed "
               "in the last second, L/s)", "",
           "| L / l_b | substeps | " + " | ".join(forms) + " |", "|---:|---:|" + "---:|" * len(forms)]
    for k in range(6):
        r0 = res["forms"][forms[0]]["settling"][k]
        md.append(f"| {r0['ratio']:g} | {r0['substeps']} | " + " | ".join(
            f"{fmt_t(res['forms'][f]['settling'][k]['settled'])} ({res['forms'][f]['settling'][k]['last']:.0e})"
            for f in forms) + " |")
    md += ["", "Hanging straight down (4 l_b), tensions started at zero, no drag: root tension / carried weight after "
               "1 frame and after 2 s (largest speed, L/s)", "",
           "| substeps | " + " | ".join(forms) + " |", "|---:|" + "---:|" * len(forms)]
    for k in range(3):
        md.append(f"| {res['forms'][forms[0]]['hanging'][k]['substeps']} | " + " | ".join(
            "{first:.3f} / {end:.3f} ({vmax:.0e})".format(**res["forms"][f]["hanging"][k]) for f in forms) + " |")
    md += ["", "### 3. First bending frequency of L = l_b/2 released straight, omega / omega1 - 1", "",
           "| substeps | " + " | ".join(forms) + " |", "|---:|" + "---:|" * len(forms)]
    for sub in (512, 8):
        md.append(f"| {sub} | " + " | ".join(
            "n/a" if res["forms"][f]["frequency"][sub] is None else f"{res['forms'][f]['frequency'][sub]:+.3%}"
            for f in forms) + " |")
    for ratio, key in (("l_b (the elastic study's swing)", "energy l_b"), ("4 l_b (a long strand swinging down)",
                                                                             "energy 4 l_b")):
        md += ["", f"### 4. Energy, L = {ratio} released horizontal, 2 s: max rise / E0 (E(2 s) / E0)", "",
               "| substeps | " + " | ".join(forms) + " |", "|---:|" + "---:|" * len(forms)]
        for sub in (1, 2, 8, 32, 128):
            md.append(f"| {sub} | " + " | ".join("{:.1e} ({:.3g})".format(*res["forms"][f][key][sub]) for f in forms)
                      + " |")
    md += ["", "Other tension updates, L = 4 l_b, max rise / E0 (E(2 s) / E0):", "",
           "| form | 1 | 2 | 8 | 32 |", "|---|---:|---:|---:|---:|"]
    for name, r in res["extra"].items():
        md.append(f"| {name} | " + " | ".join("{:.1e} ({:.3g})".format(*r[s]) for s in (1, 2, 8, 32)) + " |")
    for name, r in res["extra frequency"].items():
        fr = ", ".join(f"{s} substeps " + ("n/a" if v is None else f"{v:+.1%}") for s, v in r.items())
        el = ", ".join(f"{s} substeps {v[0]:.1e}" for s, v in res["extra energy l_b"][name].items())
        md += ["", f"{name}: frequency {fr}; energy rise on L = l_b: {el}."]
    if "current 4 l_b" in res:
        md += ["", "The present elastic solver (KKT solve, Warp kernel on the CPU, float64) on the same L = 4 l_b "
                   "swing: " + ", ".join("{} substeps {:.1e} ({:.3g})".format(s, *v)
                                          for s, v in res["current 4 l_b"].items()) + "."]
    md += traffic_markdown(res["traffic"])
    md += ["", f"Run time: {res['seconds']:.0f} s."]
    write_report(args.out, "formulation-study", res, "\n".join(md) + "\n")
    return 0


def traffic_markdown(rows) -> list:
    """The memory-traffic table (words per particle-step, x DFTL's 19): rows (name, words, where),
    words an int, a (straight, curved) pair, or text (no ratio)."""
    md = ["", "### 5. Memory traffic per free particle per step (words, float32; counted from the designs)", "",
          "| step | words | x DFTL | where |", "|---|---:|---:|---|"]
    for name, total, where in rows:
        if isinstance(total, tuple):
            words, ratio = f"{total[0]} / {total[1]}", f"{total[0] / 19:.1f} / {total[1] / 19:.1f}"
        elif isinstance(total, int):
            words, ratio = str(total), f"{total / 19:.1f}"
        else:
            words, ratio = str(total), ""
        md.append(f"| {name} | {words} | {ratio} | {where} |")
    return md


def write_report(out, stem: str, res: dict, text: str) -> None:
    """Print the report; with ``out`` also write ``{stem}-output.md`` and ``{stem}.json`` there."""
    print(text)
    if out:
        out = Path(out)
        out.mkdir(parents=True, exist_ok=True)
        (out / f"{stem}.json").write_text(json.dumps(res, indent=1, default=str))
        (out / f"{stem}-output.md").write_text(text)


if __name__ == "__main__":
    raise SystemExit(main())
