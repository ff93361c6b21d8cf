#!/usr/bin/env python3
"""Probe (not product code): does the elastic step gain from running its three sweeps (A frames,
B elimination, C back substitution and follow-the-leader) as separate launches, each compiled on
its own so that it holds only the registers it needs, and more threads are in flight? The kernel
factory's ``phases`` argument builds a kernel of some sweeps; the sweeps already hand each other
their results through global memory (frames, factor scratch), so a split run computes the same
values. Times each split against the kernel as it is on scripts/bench_elastic.py's curly groom
(float32 arithmetic, 8 substeps), prints ms per step, each variant's distance to the kernel after
one frame, and the registers of the compiled kernels (``cuobjdump --dump-resource-usage`` on
Warp's kernel cache, where the CUDA toolkit has it).

    python scripts/probe_elastic_phases.py --device cuda:0 --strands 1000000 --out DIR
    python scripts/probe_elastic_phases.py --device cuda:0 --strands 1000000 --product --arithmetic float64
"""

from __future__ import annotations

import argparse
import gc
import json
import shutil
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import warp as wp

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "scripts"))
import dftl_warp as dw  # noqa: E402
import dftl_warp.kernels.solvers.elastic as K  # noqa: E402
import dftl_warp.kernels.solvers.elastic_blocks as blocks  # noqa: E402
from bench_elastic import curly_groom  # noqa: E402
from probe_elastic_scratch import timed_frames  # noqa: E402

#: (label, [(phases, register cap), ...]); a cap of 0 leaves the kernel uncapped
VARIANTS = [
    ("A | B | C, caps 128 / 128 / 128", [("A", 128), ("B", 128), ("C", 128)]),
    ("A | B | C, caps 128 / 128 / 64", [("A", 128), ("B", 128), ("C", 64)]),
    ("A | B | C, caps 96 / 96 / 64", [("A", 96), ("B", 96), ("C", 64)]),
    ("A | B | C, caps 64 / 128 / 64", [("A", 64), ("B", 128), ("C", 64)]),
    ("A | BC, caps 96 / 128", [("A", 96), ("BC", 128)]),
    ("AB | C, caps 128 / 64", [("AB", 128), ("C", 64)]),
]


def phase_kernels(parts, scalar, real, correction):
    out = []
    for phases, cap in parts:
        caps = dict(K.CUDA_MAX_REGISTERS_F32)
        K.CUDA_MAX_REGISTERS_F32[phases] = cap or None
        out.append(K.elastic_kernel.__wrapped__(scalar, real, correction, phases=phases))
        K.CUDA_MAX_REGISTERS_F32.update(caps)
    return out


def run(pts, counts, parts, frames, substeps, device, arithmetic="float32", each=False):
    """ms a step, the positions after one frame, and with ``each`` ms a launch of each kernel alone."""
    model = dw.Model.from_strands(pts, counts, device=device, widths=80e-6)
    solver = dw.make_solver(model, "elastic", compute_precision=arithmetic)
    correction = "prior" if solver.carries_corrections else "posterior"
    real = wp.float32 if arithmetic == "float32" else wp.float64
    solver._kernels = tuple(phase_kernels(parts, model.scalar, real, correction))
    ms, x1, (state, control, dt) = timed_frames(model, solver, device, substeps, frames)
    per_kernel = []
    if each:
        kernels = solver._kernels
        for kernel in kernels:
            solver._kernels = (kernel,)
            t = time.perf_counter()
            for _ in range(16):
                solver.step(state, state, control, dt)
            wp.synchronize_device(device)
            per_kernel.append((time.perf_counter() - t) / 16 * 1e3)
        solver._kernels = kernels
    del solver, state
    gc.collect()
    return ms, x1, per_kernel


def registers() -> list[str]:
    """Registers of every compiled elastic-step kernel in Warp's kernel cache."""
    tool = shutil.which("cuobjdump") or "/usr/local/cuda/bin/cuobjdump"
    if not Path(tool).exists():
        return ["cuobjdump not found"]
    rows = []
    for cubin in sorted(Path(wp.config.kernel_cache_dir).rglob("*.cubin")):
        res = subprocess.run([tool, "--dump-resource-usage", str(cubin)], capture_output=True, text=True)
        name = None
        for line in res.stdout.splitlines():
            if "Function" in line:
                name = line.split("Function")[-1].strip(" :")
            elif "REG:" in line and name and "elastic_step" in name:
                rows.append(f"{cubin.parent.name}: {line.strip()}")
    return rows


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--device", default="cuda:0")
    ap.add_argument("--strands", type=int, default=1000000)
    ap.add_argument("--frames", type=int, default=3)
    ap.add_argument("--out", type=Path)
    ap.add_argument("--arithmetic", default="float32", choices=("float32", "float64"))
    ap.add_argument("--product", action="store_true",
                    help="only the product's split (kernels/solvers/elastic.py's caps), with each kernel timed")
    ap.add_argument("--kkt", nargs="*", default=[],
                    help="also time the product's split with these KKT_INVERSE forms (elastic_blocks.py)")
    args = ap.parse_args()
    wp.init()
    pts, counts = curly_groom(args.strands)
    caps = K.CUDA_MAX_REGISTERS_F32 if args.arithmetic == "float32" else dict.fromkeys(K.CUDA_MAX_REGISTERS_F32, 0)
    variants = VARIANTS
    if args.product:
        variants = [(" | ".join(K.CUDA_PHASES) + ", caps " + " / ".join(str(caps[p] or "none") for p in K.CUDA_PHASES),
                     [(p, caps[p]) for p in K.CUDA_PHASES])]
    base_ms, base_x, _ = run(pts, counts, [("ABC", caps["ABC"])], args.frames + 2, 8, args.device, args.arithmetic)
    rows = [(f"ABC (one kernel), cap {caps['ABC'] or 'none'}", base_ms, 0.0)]
    print(f"{args.arithmetic} arithmetic. {rows[0][0]}: {base_ms:.3f} ms/step", flush=True)
    default_kkt = blocks.KKT_INVERSE
    variants = [(label, parts, default_kkt) for label, parts in variants]
    variants += [(f"{variants[-1][0]}, KKT inverse {kkt}", variants[-1][1], kkt) for kkt in args.kkt]
    for label, parts, kkt in variants:
        blocks.KKT_INVERSE = kkt
        ms, x, each = run(pts, counts, parts, args.frames, 8, args.device, args.arithmetic, each=args.product)
        blocks.KKT_INVERSE = default_kkt
        diff = float(np.abs(x - base_x).max())
        rows.append((label, ms, diff, each))
        print(f"{label}: {ms:.3f} ms/step, max |x - x_kernel| after 1 frame {diff:.3g} m", flush=True)
        if each:
            print("  each kernel alone, ms a launch: " + ", ".join(f"{p}: {t:.3f}" for (p, _), t in zip(parts, each)))
    regs = registers()
    print("\n".join(regs))
    if args.out:
        args.out.mkdir(parents=True, exist_ok=True)
        name = f"elastic-phases-{args.arithmetic}{'-product' if args.product else ''}.json"
        (args.out / name).write_text(json.dumps({"device": args.device, "strands": args.strands,
                                                  "arithmetic": args.arithmetic, "rows": rows,
                                                  "registers": regs}, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
