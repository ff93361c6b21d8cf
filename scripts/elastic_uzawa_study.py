#!/usr/bin/env python3
"""Candidate "U" for a cheaper elastic step: in-step tensions by inexact Uzawa on a constant bending matrix.

A numpy/scipy study on the CPU (no Warp kernels), the follow-up of candidate L
(scripts/elastic_formulation_study.py, docs/elastic/formulation-study.md), measured with that
script's harnesses (statics against the elastica, settling, hanging, frequency, energy). One step of
length h (s) of a strand of N + 1 particles (0 the kinematic root at rest, a clamp ghost behind it;
masses, bending weights W, D and the energy from ``RodGroup``; straight rest shapes, b = 0):

1. r = M v + h (M g - K x), A = M (1 + h drag) + h^2 K [+ h^2 K_T], K = D^T W D the constant scalar
   pentadiagonal bending matrix (the same for x, y, z; factored once per h when there is no K_T),
   K_T the isotropic string stiffness max(T_i, 0) / l_i of the last step's tensions T = -lam;
2. the KKT system A v = r + h J^T lam, J v = 0 (J_i v = t_i . (v_i - v_{i-1}), t the unit tangents
   at x^n), solved for lam on its Schur complement S lam = -J A^-1 r / h, S = J A^-1 J^T, from
   lam^0 (warm: the last step's lam; cold: 0), with v^k = A^-1 (r + h J^T lam^k) and R rounds of
   - Richardson (inexact Uzawa), lam <- lam - P^-1 (J v) / h, or
   - preconditioned conjugate gradients on S (one A^-1 solve per iteration),
   P one of: P_M = J M^-1 J^T (what L used), P_A = J diag(A)^-1 J^T, or P_B, given by its inverse
   P_B^-1 = P_M^-1 + h^2 G^T W G (+ h^2 diag(max(T, 0) / l) with K_T), G^T W G the tridiagonal
   bending stiffness of the segment stretches: exact (P_B = S) for a straight strand, where the
   stretch and transverse motions decouple. R rounds cost R + 1 pentadiagonal solves. "exact":
   S formed densely and solved (R = infinity, the converged reference of the same splitting);
3. p = x + h v^R, follow the leader, c = x_new - p, v_new = (x_new - x) / h - s c_{i+1} / h.

With K_T from the *kernel's* sign (max(+lam, 0), what kernels/solvers/elastic.py does with the
tensions it writes) and the exact solve, the step is the present elastic solver's (J at x^n,
K_T, s = 1): the row "present (replica)" checks the harness against the Warp kernel's energy.

The harnesses of elastic_formulation_study build ``efs.Strand``; this script sets it to
:class:`UzawaStrand` (a subclass), so they measure candidate U unchanged.

    python scripts/elastic_uzawa_study.py                       # prints the report (~3 min on 2 cores)
    python scripts/elastic_uzawa_study.py --out docs/elastic    # also writes uzawa-study-output.md, .json
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

import numpy as np
from scipy.linalg import cho_solve_banded, cholesky_banded, solve_banded, solveh_banded

sys.path.insert(0, str(Path(__file__).resolve().parent))
import elastic_formulation_study as efs  # noqa: E402

N, G = efs.N, efs.G
SUBSTEPS = (1, 2, 8, 32, 128)


class UzawaStrand(efs.Strand):
    """Candidate U; ``precond`` "M", "A", "B" (Richardson), "CG-M", "CG-A", "CG-B" (PCG) or "exact";
    ``rounds`` R; ``warm`` (lam^0 = last step's lam, else 0); ``string`` None, "tension" (K_T of the
    last tensions) or "kernel" (the present kernel's sign, max(lam, 0)); ``s`` DFTL's correction."""

    def __init__(self, L, direction=(1.0, 0.0, 0.0), *, precond="CG-B", rounds=1, warm=True, string=None,
                 drag=0.0, s=1.0):
        super().__init__(L, direction, update="in-step", string=False, drag=drag, s=s)
        self.precond, self.rounds, self.warm, self.kt = precond, rounds, warm, string

    # -- linear algebra of one step
    def J(self, t, v):
        """Length rates t_i . (v_i - v_{i-1}) (N), v (N, 3) on the free particles, v_0 = 0."""
        jv = np.sum(t * v, axis=1)
        jv[1:] -= np.sum(t[1:] * v[:-1], axis=1)
        return jv

    def string_stiffness(self):
        """max(T_i, 0) / l_i (N/m) of the last step's multipliers, with the chosen sign."""
        return np.maximum(self.lam if self.kt == "kernel" else -self.lam, 0.0) / self.l

    def bands(self, h, t):
        """Upper bands (3, N) of A; the bending part is cached per h."""
        if self.factor_h != h:
            self.ab0, self.factor_h = self.matrix_bands(h, t), h    # the base class's, string=False
            if not self.kt:
                self.factor = cholesky_banded(self.ab0)
        if not self.kt:
            return self.ab0
        k = self.string_stiffness()
        ab = self.ab0.copy()
        ab[2] += h * h * (k + np.r_[k[1:], 0.0])
        ab[1, 1:] -= h * h * k[1:]
        return ab

    def preconditioner(self, kind, h, t, diag_a):
        """z = P^-1 b for P_M, P_A or P_B (tridiagonal Thomas solves, plus a tridiagonal product for P_B)."""
        d = diag_a if kind == "A" else self.m * (1 + h * self.drag)
        inv = 1.0 / d
        P = np.zeros((3, N))                              # J diag(d)^-1 J^T
        off = -np.sum(t[1:] * t[:-1], axis=1) * inv[:-1]
        P[0, 1:], P[1], P[2, :-1] = off, inv + np.r_[0.0, inv[:-1]], off
        if kind != "B":
            return lambda b: solve_banded((1, 1), P, b)
        W, l = self.W, self.l                             # G^T W G: segment k in rows k-1 (+t_k/l_k), k (-t_k/l_k)
        gd = W / l ** 2
        gd[:-1] += W[1:] / l[:-1] ** 2
        if self.kt:
            gd = gd + self.string_stiffness()
        go = -W[1:] * np.sum(t[1:] * t[:-1], axis=1) / (l[1:] * l[:-1])

        def apply(b):
            q = gd * b
            q[1:] += go * b[:-1]
            q[:-1] += go * b[1:]
            return solve_banded((1, 1), P, b) + h * h * q
        return apply

    def step(self, h):
        x = self.x
        t = self.tangents(x)
        ab = self.bands(h, t)
        if self.kt:                                        # A changes every step
            solve = lambda b: solveh_banded(ab, b)  # noqa: E731
        else:
            solve = lambda b: cho_solve_banded((self.factor, False), b)  # noqa: E731
        r = self.m[:, None] * self.v[1:] + h * (self.m[:, None] * G + self.bending_force(x))
        lam = self.lam.copy() if self.warm else np.zeros(N)
        v = solve(r + h * self.constraint_force(lam, t))
        kind = self.precond
        if kind == "exact":
            S = schur_complement(t, solve(np.eye(N)))
            lam = lam - np.linalg.solve(S, self.J(t, v)) / h
            v = solve(r + h * self.constraint_force(lam, t))
        elif not kind.startswith("CG"):                    # Richardson: inexact Uzawa
            pinv = self.preconditioner(kind, h, t, ab[2])
            for _ in range(self.rounds):
                lam = lam - pinv(self.J(t, v)) / h
                v = solve(r + h * self.constraint_force(lam, t))
        else:                                              # PCG on S lam = -J A^-1 r / h
            pinv = self.preconditioner(kind[3:], h, t, ab[2])
            res = -self.J(t, v) / h
            z = pinv(res)
            p, rz = z, res @ z
            for _ in range(self.rounds):
                w = solve(self.constraint_force(p, t))    # A^-1 J^T p
                Sp = self.J(t, w)
                a = rz / (p @ Sp)
                lam, v, res = lam + a * p, v + a * h * w, res - a * Sp
                z = pinv(res)
                rz, rz_old = res @ z, rz
                p = z + (rz / rz_old) * p
        self.lam = lam
        xn = self.follow_the_leader(x, x[1:] + h * v)
        c = np.zeros_like(xn)
        c[1:] = xn[1:] - x[1:] - h * v
        vn = (xn - x) / h
        vn[:-1] -= self.s * c[1:] / h                      # DFTL: particle i loses s c_{i+1} / h
        vn[0] = 0.0
        self.x, self.v = xn, vn

    def follow_the_leader(self, x, p):
        """Exact segment lengths from the root (python floats: the loop is the step's slowest part)."""
        out = [x[0].tolist()]
        px, py, pz = out[0]
        for li, (qx, qy, qz) in zip(self.l.tolist(), p.tolist()):
            dx, dy, dz = qx - px, qy - py, qz - pz
            f = li / math.sqrt(dx * dx + dy * dy + dz * dz)
            px, py, pz = px + f * dx, py + f * dy, pz + f * dz
            out.append([px, py, pz])
        return np.array(out)


efs.Strand = UzawaStrand          # the harnesses of elastic_formulation_study now build candidate U


def schur_complement(t, Ainv):
    """Dense S = J A^-1 J^T = sum over x, y, z of J_c A^-1 J_c^T (N x N), t the unit tangents (N, 3)."""
    S = np.zeros((N, N))
    for c in range(3):
        Jc = np.diag(t[:, c]) - np.diag(t[1:, c], -1)
        S += Jc @ Ainv @ Jc.T
    return S


def spectrum(substeps=8, frames=24):
    """Eigenvalue range of P^-1 S (Richardson converges iff all lie in (0, 2)) for P_M, P_A, P_B on an
    L = 4 l_b cantilever (drag 20/s): straight at release and sagged after ``frames`` frames."""
    st = UzawaStrand(4 * efs.LB, precond="exact", drag=20.0)
    h, out = 1.0 / (efs.FPS * substeps), {}
    for when in ("straight", f"sagged after {frames / efs.FPS:g} s"):
        if when != "straight":
            for _ in range(frames):
                efs.frame(st, substeps)
        t = st.tangents(st.x)
        ab = st.bands(h, t)
        S = schur_complement(t, cho_solve_banded((st.factor, False), np.eye(N)))
        for kind in ("M", "A", "B"):
            pinv = st.preconditioner(kind, h, t, ab[2])
            ev = np.linalg.eigvals(np.stack([pinv(e) for e in np.eye(N)], 1) @ S).real
            out[f"{when}, P_{kind}"] = (float(ev.min()), float(ev.max()))
    return out


def form(precond, rounds=1, warm=True, string=None, s=1.0):
    return dict(precond=precond, rounds=rounds, warm=warm, string=string, s=s)


def label(f):
    name = {"M": "P_M", "A": "P_A", "B": "P_B", "CG-M": "PCG P_M", "CG-A": "PCG P_A", "CG-B": "PCG P_B",
            "exact": "exact S"}[f["precond"]]
    if f["precond"] != "exact":
        name += f", R = {f['rounds']}, " + ("warm" if f["warm"] else "cold")
    if f["string"]:
        name += " + K_T" + (" (kernel's sign)" if f["string"] == "kernel" else "")
    return name + ("" if f["s"] == 1.0 else f", s = {f['s']:g}")


#: the screen: energy of L = 4 l_b released horizontal, no drag, at 1-128 substeps, for every variant
SCREEN = ([form("exact"), form("exact", string="tension"), form("exact", string="kernel")]
          + [form(p, R, w) for p in ("M", "A", "CG-M", "CG-A", "B", "CG-B") for R in (1, 2, 3, 5) for w in (True, False)]
          + [form(p, R, w, "tension") for p in ("B", "CG-A", "CG-B") for R in (1, 2, 3) for w in (True, False)]
          + [form("exact", s=0.0), form("exact", string="tension", s=0.0), form("CG-B", 2, s=0.0),
             form("CG-B", 1, string="tension", s=0.0)])
#: every measure of the previous study, for the references and the best finite-R variants of the screen
BATTERY = [form("exact"), form("exact", string="tension"), form("CG-B", 2), form("CG-B", 1, string="tension")]

#: words read + written per free particle per step, float32, by sweep, as elastic/formulation-study.md
#: table 5 counts them (tip -> root sweeps build right-hand sides and forward-substitute, root -> tip
#: sweeps back-substitute; a Thomas solve of P has its forward pass in one sweep, its back pass in the next)
PAIR0 = [("S1 reads x 3, v 3, lam 1, mass 1, W 1, length 1, factor 3; writes y 3", 16),
         ("S2 reads y 3, multipliers 2, x 3, length 1, mass 1, W 1 (v^0, J v^0, Thomas forward pass of P_M, "
          "G^T W G b); writes Thomas 2 (c', d'), G^T W G b 1", 14)]
ROUND = [("S1 reads Thomas 2, G^T W G b 1, lam 1, x 3, v 3, mass 1, W 1, length 1, factor 3 (lam update, "
          "r + h J^T lam rebuilt); writes lam 1, y 3", 20),
         ("S2 as pair 0's, except in the last round", 14)]
LAST = [("last S2 reads y 3, multipliers 2, x 3, length 1; follow the leader writes x 3, v 3", 15)]
CG1 = [("S1 as pair 0's", 16),
       ("S2 as pair 0's, also writes v^0 3, residual 1", 18),
       ("S1' reads Thomas 2, G^T W G b 1, residual 1, x 3, length 1, factor 3 (z, r.z, y = L^-1 J^T z); "
        "writes y 3, z 1", 15),
       ("S2' reads y 3, multipliers 2, x 3, length 1 (w = A^-1 J^T z, z.Sz); writes w 3", 12),
       ("S3 (root -> tip, alpha known) reads v^0 3, w 3, x 3, length 1, lam 1, z 1; writes x 3, v 3, lam 1", 19)]
KT = 4       # K_T: factor written in the first S1 (pivot, 2 multipliers) 3; the last tension read again in S2 1


def traffic_rows():
    total = lambda parts: sum(w for _, w in parts)  # noqa: E731
    text = lambda parts: "; ".join(t for t, _ in parts)  # noqa: E731
    rows = [("DFTL, prior form (docs/benchmarks.md)", 19, "x 3+3, v 3+3, c 3+3, rest length 1"),
            ("elastic (present), straight / curved (elastic/formulation-study.md)", (90, 111), "KKT with 4x4 blocks"),
            ("L1 (elastic/formulation-study.md)", 36, "tensions carried from the last step, tridiagonal update")]
    for R in (1, 2, 3, 5):
        words = total(PAIR0) + R * ROUND[0][1] + (R - 1) * ROUND[1][1] + total(LAST)
        rows.append((f"U, Richardson P_B, R = {R}, warm", words,
                     f"pair 0: {text(PAIR0)}; R rounds: {text(ROUND)}; {text(LAST)}" if R == 1 else "as R = 1, "
                     "+34 a round"))
    rows.append(("U, Richardson P_M instead of P_B", "-3 a round", "no G^T W G b (W read 1, write 1, read 1)"))
    rows.append(("U, cold start", "-1", "lam not read in the first S1"))
    rows.append(("U, + K_T (A factored every step)", f"+{KT}", "factor written in the first S1 (pivot, 2 "
                 "multipliers) 3, read where the constant factor was; the last tension read again in S2 1"))
    rows.append(("U, PCG P_B, R = 1, warm", total(CG1), text(CG1)))
    rows.append(("U, PCG P_B, R = 1, warm, + K_T", total(CG1) + KT, "as above, + K_T"))
    rows.append(("U, PCG P_B, R = 2, warm", f">= {total(CG1) + 34}", "R = 1 + at least a Richardson round's sweep "
                 "pair (34; p, w and y_p add more, not itemised)"))
    rows.append(("U, state only (if the scratch stayed on chip; an estimate)", 20,
                 "x 3+3, v 3+3, lam 1+1, mass 1, W 1, length 1, factor 3"))
    return rows


# ------------------------------------------------------------------------------------------ report
def e_cell(v):
    return "{:.1e} ({:.3g})".format(*v)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", help="folder for uzawa-study-output.md and uzawa-study.json")
    args = ap.parse_args()
    t0 = time.perf_counter()
    res = {"l_b (m)": efs.LB, "screen": {}, "battery": {}}
    for f in SCREEN:
        with np.errstate(all="ignore"):
            res["screen"][label(f)] = {s: v for s, v in efs.energy(f, 4.0, SUBSTEPS).items()}
    res["t screen"] = time.perf_counter() - t0
    for f in BATTERY:
        r = res["battery"][label(f)] = {}
        r["statics"], r["spread"] = efs.statics(f)
        r["settling"] = efs.settling(f)
        r["hanging"] = efs.hanging(f)
        r["frequency"] = efs.frequency(f)
        r["energy l_b"] = efs.energy(f, 1.0, SUBSTEPS)
        r["energy 4 l_b"] = res["screen"][label(f)]
    best = form("CG-B", 1, string="tension")
    res["fine"] = {label(best): efs.energy(best, 4.0, (512,))}
    res["frequency s = 0"] = {label(f): efs.frequency(f) for f in (form("CG-B", 1, string="tension", s=0.0),)}
    res["spectrum"] = spectrum()
    res["traffic"] = traffic_rows()
    res["present 4 l_b"] = efs.current_energy(4.0, SUBSTEPS)   # the Warp kernel, for comparison
    res["seconds"] = time.perf_counter() - t0

    md = [f"80 um hair, l_b = {100 * efs.LB:.2f} cm, {N} segments, float64, straight rest shapes (b = 0), root "
          "clamped by the ghost, tensions cold at the start of every run. Limits: statics within 2% of L of the "
          "elastica, sag spread over 2/8/32 substeps within 1% of L; frequency within 3%; energy never rising more "
          "than 1e-3 E0.", "",
          "### 0. Screen: L = 4 l_b released horizontal, no drag, 2 s: max rise / E0 (E(2 s) / E0)", "",
          "| variant | " + " | ".join(f"{s}" for s in SUBSTEPS) + " |", "|---|" + "---:|" * len(SUBSTEPS)]
    for name, r in res["screen"].items():
        md.append(f"| {name} | " + " | ".join(e_cell(r[s]) for s in SUBSTEPS) + " |")
    md += ["", "The present elastic solver (its Warp kernel on the CPU, float64, measured in this run: "
               "elastic_formulation_study.current_energy): "
               + ", ".join(e_cell(v) for _, v in sorted(res["present 4 l_b"].items())) + "."]
    forms = list(res["battery"])
    head = ["| L / l_b | substeps | " + " | ".join(forms) + " |", "|---:|---:|" + "---:|" * len(forms)]
    md += ["", "### 1. Statics: horizontal cantilevers after 4 s (drag 20/s), max distance to the elastica / L "
               "(largest speed at the end, L/s)", ""] + head
    B = res["battery"]
    for k, r0 in enumerate(B[forms[0]]["statics"]):
        md.append(f"| {r0['ratio']:g} | {r0['substeps']} | " + " | ".join(
            f"{B[f]['statics'][k]['error']:.5f} ({B[f]['statics'][k]['speed']:.0e})" for f in forms) + " |")
    md += ["", "| sag spread over 2/8/32 substeps / L | " + " | ".join(forms) + " |", "|---|" + "---:|" * len(forms)]
    for k, ratio in enumerate((0.5, 1.0, 2.0, 4.0)):
        md.append(f"| L = {ratio:g} l_b | " + " | ".join(f"{B[f]['spread'][k]:.1e}" for f in forms) + " |")
    md += ["", "### 2. Settling: released horizontal, drag 20/s, 8 s: time to stay below 1e-3 L/s (largest speed "
               "in the last second, L/s)", ""] + head
    for k, r0 in enumerate(B[forms[0]]["settling"]):
        md.append(f"| {r0['ratio']:g} | {r0['substeps']} | " + " | ".join(
            f"{efs.fmt_t(B[f]['settling'][k]['settled'])} ({B[f]['settling'][k]['last']:.0e})" for f in forms) + " |")
    md += ["", "Hanging straight down (4 l_b), tensions started at zero, no drag: root tension / carried weight after "
               "1 frame and after 2 s (largest speed, L/s)", "",
           "| substeps | " + " | ".join(forms) + " |", "|---:|" + "---:|" * len(forms)]
    for k, r0 in enumerate(B[forms[0]]["hanging"]):
        md.append(f"| {r0['substeps']} | " + " | ".join(
            "{first:.3f} / {end:.3f} ({vmax:.0e})".format(**B[f]["hanging"][k]) for f in forms) + " |")
    md += ["", "### 3. First bending frequency of L = l_b/2 released straight, omega / omega1 - 1", "",
           "| substeps | " + " | ".join(forms) + " |", "|---:|" + "---:|" * len(forms)]
    for sub in (512, 8):
        md.append(f"| {sub} | " + " | ".join("n/a" if B[f]["frequency"][sub] is None
                                             else f"{B[f]['frequency'][sub]:+.3%}" for f in forms) + " |")
    for name, r in res["frequency s = 0"].items():
        md += ["", f"{name}: " + ", ".join(f"{s} substeps " + ("n/a" if v is None else f"{v:+.3%}")
                                           for s, v in r.items()) + "."]
    for title, key in (("l_b (the elastic study's swing)", "energy l_b"), ("4 l_b (the screen's rows)", "energy 4 l_b")):
        md += ["", f"### 4. Energy, L = {title} released horizontal, 2 s: max rise / E0 (E(2 s) / E0)", "",
               "| substeps | " + " | ".join(forms) + " |", "|---:|" + "---:|" * len(forms)]
        for sub in SUBSTEPS:
            md.append(f"| {sub} | " + " | ".join(e_cell(B[f][key][sub]) for f in forms) + " |")
    for name, r in res["fine"].items():
        md += ["", f"{name}, L = 4 l_b at 512 substeps: {e_cell(r[512])}."]
    md += ["", "### Preconditioners: eigenvalues of P^-1 S, L = 4 l_b cantilever, 8 substeps, drag 20/s (Richardson "
               "converges iff all lie in (0, 2); PCG's rate follows max / min)", "",
           "| strand, P | min | max |", "|---|---:|---:|"]
    md += [f"| {k} | {a:.3g} | {b:.3g} |" for k, (a, b) in res["spectrum"].items()]
    md += efs.traffic_markdown(res["traffic"])
    md += ["", f"Run time: {res['seconds']:.0f} s (screen {res['t screen']:.0f} s)."]
    efs.write_report(args.out, "uzawa-study", res, "\n".join(md) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
