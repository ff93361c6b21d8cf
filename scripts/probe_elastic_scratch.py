#!/usr/bin/env python3
"""Probe (not product code): can the elastic step's factor scratch stay on chip? A persistent launch
of a few threads per SM loops over the strands, its scratch either in per-thread local matrices
(``PROBE_MODE=local``) or in a per-thread slice of the global scratch (``PROBE_MODE=global``, the
default). Writes a text-transformed copy of kernels/solvers/elastic.py beside it (removed at the
end), and times it against the kernel as it is on scripts/bench_elastic.py's curly groom (float32
arithmetic, 8 substeps), printing ms per step and each variant's distance to it after one frame.

    PROBE_MODE=local python scripts/probe_elastic_scratch.py cuda:0 1000000 32,64,128
    PROBE_MODE=global python scripts/probe_elastic_scratch.py cuda:0 1000000 64,128,256
    PROBE_MODE=shared python scripts/probe_elastic_scratch.py cuda:0 1000000 8,14   # block sizes

``PROBE_MODE=shared`` keeps one thread per strand, launched in blocks of the given sizes, and moves
the scratch into a private row of shared memory per thread (at most 14 threads a block: 48 KB).

Measured on one H200, 2026-11-28 (JSONs in docs/elastic/scratch-probe/; docs/elastic.md "Cost"):
every variant equal to the kernel to the bit after a frame; the kernel as it is 7.1 ms a step; global
slices 37.8 / 21.2 / 11.9 ms at 64 / 128 / 256 threads per SM, local 66.6 / 38.5 / 21.4 at 32 / 64 /
128, shared rows 37.8 / 38.7 ms in blocks of 8 / 14. The time per strand of a thread is the same
wherever its scratch lives; the step scales with the threads in flight. The figures of 2026-11-27
(16-130x slower, results moved by 0.36 m) were wrong: the launcher never matched the kernel's key
(``elastic_kernel__locals__elastic_step``), so its launch size was never applied and every thread of
the persistent loops stepped every strand.
"""
import gc, importlib, json, os, re, sys, time
from pathlib import Path

import numpy as np
import warp as wp

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "scripts"))  # noqa: E402
import dftl_warp as dw
import dftl_warp.solvers.elastic as E
from bench_elastic import curly_groom

SRC = (ROOT / "kernels/solvers/elastic.py").read_text()
MAXP = 33
MODE = os.environ.get("PROBE_MODE", "global")


def transform_global(threads: int) -> str:
    """The scratch in the global arrays, but one slice per thread of a persistent launch (index k T + t)."""
    lines = SRC.split("\n")
    start = next(i for i, l in enumerate(lines) if l == "        s = wp.tid()")
    end = next(i for i, l in enumerate(lines) if l == "    return elastic_step")
    out = lines[:start] + ["        t = wp.tid()", f"        for s in range(t, strand_base.shape[0], {threads}):"]
    for l in lines[start + 1:end]:
        if l.strip() == "return":
            l = l.replace("return", "continue")
        out.append(("    " + l) if l.strip() else l)
    out += lines[end:]
    s = "\n".join(out)
    slot = f"k * {threads} + t"
    for a in ("factor_inv[kk]", "factor_up[kk]", "factor_rhs[kk]"):
        assert s.count(a) == 2, (a, s.count(a))
        s = s.replace(a, a.replace("kk", slot))
    return s


def transform(threads: int) -> str:
    lines = SRC.split("\n")
    start = next(i for i, l in enumerate(lines) if l == "        s = wp.tid()")
    end = next(i for i, l in enumerate(lines) if l == "    return elastic_step")
    out = lines[:start] + [f"        for s in range(wp.tid(), strand_base.shape[0], {threads}):"]
    for l in lines[start + 1:end]:
        if l.strip() == "return":
            l = l.replace("return", "continue")
        out.append(("    " + l) if l.strip() else l)
    out += lines[end:]
    s = "\n".join(out)
    s = s.replace('    prior = correction == "prior"\n',
                  '    prior = correction == "prior"\n'
                  f'    ScrInv = wp.types.matrix(shape=({MAXP}, 10), dtype=real)\n'
                  f'    ScrRow = wp.types.matrix(shape=({MAXP}, 4), dtype=real)\n', 1)
    ind = " " * 12
    decl = (f"{ind}loc_inv = ScrInv()\n{ind}loc_u0 = ScrRow()\n{ind}loc_u1 = ScrRow()\n{ind}loc_u2 = ScrRow()\n"
            f"{ind}loc_rhs = ScrRow()\n")
    marker = f"{ind}# ---- B: forces and elimination"
    assert marker in s
    s = s.replace(marker, decl + marker, 1)
    rep = [
        ("factor_inv[kk] = Di_packed", "loc_inv[k] = Di_packed"),
        ("factor_rhs[kk] = wk", "loc_rhs[k] = wk"),
        ("yk = factor_rhs[kk]", "yk = loc_rhs[k]"),
        ("unpack_symmetric(factor_inv[kk])", "unpack_symmetric(loc_inv[k])"),
    ]
    for a, b in rep:
        assert s.count(a) == 1, a
        s = s.replace(a, b)
    m = re.search(r"\n( +)factor_up\[kk\] = B1\n", s)
    sp = m.group(1)
    s = s.replace(m.group(0), f"\n{sp}loc_u0[k] = B1[0]\n{sp}loc_u1[k] = B1[1]\n{sp}loc_u2[k] = B1[2]\n", 1)
    m = re.search(r"\n( +)yk = yk - wp.transpose\(factor_up\[kk\]\) \* vec3\(z1\[0\], z1\[1\], z1\[2\]\)\n", s)
    sp = m.group(1)
    s = s.replace(m.group(0), (f"\n{sp}r0 = loc_u0[k]\n{sp}r1 = loc_u1[k]\n{sp}r2 = loc_u2[k]\n"
                               f"{sp}Bk = mat34(r0[0], r0[1], r0[2], r0[3], r1[0], r1[1], r1[2], r1[3], r2[0], r2[1], "
                               f"r2[2], r2[3])\n{sp}yk = yk - wp.transpose(Bk) * vec3(z1[0], z1[1], z1[2])\n"), 1)
    assert "factor_inv[" not in s and "factor_up[" not in s and "factor_rhs[" not in s
    return s


#: scratch words per particle: D^-1 packed (10), B_{k-1,k} (12), w (4)
WORDS = 26


def transform_shared(block: int) -> str:
    """One thread per strand as the kernel is, launched in blocks of ``block`` threads, the factor
    scratch in a private row of shared memory per thread (``fused.shared_row_func``: [slot][thread],
    33 x 26 float32 words, 3.4 KB a thread): 14 threads fill the 48 KB a block may hold statically."""
    s = SRC
    s = s.replace('    prior = correction == "prior"\n',
                  '    prior = correction == "prior"\n'
                  f'    row = shared_row_func(real, {MAXP * WORDS}, {block})\n', 1)
    s = s.replace("from ..core.layout import particle\n",
                  "from ..core.layout import particle\nfrom .fused import shared_row_func\n", 1)

    def reads(first, n):
        return ", ".join(f"row(k * {WORDS} + {first + c}, real(0.0), 0)" for c in range(n))

    m = re.search(r"\n( +)factor_inv\[kk\] = Di_packed\n", s)
    sp = m.group(1)
    writes = "".join(f"{sp}row(k * {WORDS} + {c}, Di_packed[{c}], 1)\n" for c in range(10))
    writes += "".join(f"{sp}row(k * {WORDS} + {10 + 4 * i + j}, B1[{i}, {j}], 1)\n" for i in range(3) for j in range(4))
    writes += "".join(f"{sp}row(k * {WORDS} + {22 + c}, wk[{c}], 1)\n" for c in range(4))
    old = f"\n{sp}factor_inv[kk] = Di_packed\n{sp}factor_up[kk] = B1\n{sp}factor_rhs[kk] = wk\n"
    assert old in s
    s = s.replace(old, "\n" + writes, 1)
    rep = [("yk = factor_rhs[kk]", f"yk = vec4({reads(22, 4)})"),
           ("wp.transpose(factor_up[kk])", f"wp.transpose(mat34({reads(10, 12)}))"),
           ("unpack_symmetric(factor_inv[kk])", f"unpack_symmetric(vec10({reads(0, 10)}))")]
    for a, b in rep:
        assert s.count(a) == 1, a
        s = s.replace(a, b)
    assert "factor_inv[" not in s and "factor_up[" not in s and "factor_rhs[" not in s
    return s


def load(threads: int):
    name = f"elastic_probe_{threads}"
    text = {"global": transform_global, "shared": transform_shared}.get(MODE, transform)(threads)
    (ROOT / "kernels/solvers" / f"{name}.py").write_text(text)
    return importlib.import_module(f"dftl_warp.kernels.solvers.{name}")


class Launcher:
    def __init__(self):
        self.probe = None
    def __getattr__(self, a):
        return getattr(wp, a)
    def launch(self, kernel, dim=None, **kw):
        if self.probe is not None and "elastic_step" in getattr(kernel, "key", ""):
            if MODE != "shared":   # shared: every strand's thread, in blocks of probe[1]
                dim = self.probe[0]
            kw["block_dim"] = self.probe[1]
        return wp.launch(kernel, dim=dim, **kw)


def timed_frames(model, solver, device, substeps, frames):
    """(median ms a step over ``frames`` frames of ``substeps`` substeps after a first frame, the
    positions after that first frame, (state, control, dt))."""
    state, control = solver.state(), model.control()
    dt = 1.0 / (24 * substeps)
    solver.advance(state, control, dt, substeps)
    wp.synchronize_device(device)
    x1 = model.points_from_device(state.positions).copy()
    times = []
    for _ in range(frames):
        wp.synchronize_device(device)
        t = time.perf_counter()
        solver.advance(state, control, dt, substeps)
        wp.synchronize_device(device)
        times.append(time.perf_counter() - t)
    return float(np.median(times)) / substeps * 1e3, x1, (state, control, dt)


def run(pts, counts, probe, frames, substeps, device):
    lau = E.wp if isinstance(E.wp, Launcher) else Launcher()
    E.wp = lau
    orig = E.elastic_step_kernels
    if probe is not None:
        mod = load(probe[0])
        E.elastic_step_kernels = lambda *a: mod.elastic_step_kernels(*a[:-1], False)  # one kernel
    lau.probe = probe
    try:
        model = dw.Model.from_strands(pts, counts, device=device, widths=80e-6)
        solver = dw.make_solver(model, "elastic", compute_precision="float32")
        ms, x1, _ = timed_frames(model, solver, device, substeps, frames)
        return ms, x1
    finally:
        E.elastic_step_kernels = orig
        lau.probe = None
        gc.collect()


def main():
    device = sys.argv[1]
    strands = int(sys.argv[2])
    per_sm = [int(v) for v in sys.argv[3].split(",")]
    out = Path(sys.argv[4]) if len(sys.argv) > 4 else None
    wp.init()
    sms = wp.get_device(device).sm_count if device.startswith("cuda") else 1
    pts, counts = curly_groom(strands)
    rows = []
    base_ms, base_x = run(pts, counts, None, 5, 8, device)
    rows.append(("global scratch (as it is), all strands", base_ms, 0.0))
    print(f"baseline: {base_ms:.3f} ms/step", flush=True)
    for p in per_sm:
        for block in ((p,) if MODE == "shared" else (32,) if p <= 32 else (64,)):
            threads = p if MODE == "shared" else sms * p
            ms, x = run(pts, counts, (threads, block), 3, 8, device)
            diff = float(np.abs(x - base_x).max())
            what = f"{p} threads/SM ({threads})" if MODE != "shared" else "one thread per strand"
            rows.append((f"{MODE} scratch, {what}, blocks of {block}", ms, diff))
            print(f"{rows[-1][0]}: {ms:.3f} ms/step, max |x - x_base| after 1 frame {diff:.3g} m", flush=True)
    if out:
        out.mkdir(parents=True, exist_ok=True)
        (out / "elastic-local.json").write_text(json.dumps({"device": device, "strands": strands, "sms": sms,
                                                            "rows": rows}, indent=1))
    for f in (ROOT / "kernels/solvers").glob("elastic_probe_*.py"):
        f.unlink()


if __name__ == "__main__":
    main()
