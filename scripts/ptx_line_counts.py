#!/usr/bin/env python3
"""Static PTX instructions of the elastic step kernel per line of kernels/solvers/elastic.py,
compiled ahead of time for a CUDA architecture with Warp's NVRTC (no GPU needed) with line info:
each instruction counts for the kernel line it was generated from (inlined helpers and Warp's
builtins count for the line that called them). Static counts: a loop body counts once, a rarely
taken branch (``wp.svd3``) fully.

    python scripts/ptx_line_counts.py --arch 90 --arithmetic float32 --top 40
"""

from __future__ import annotations

import argparse
import collections
import re
import sys
import tempfile
from pathlib import Path

import numpy as np

KERNEL = Path(__file__).resolve().parents[1] / "kernels" / "solvers" / "elastic.py"


def line_counts(ptx: str) -> collections.Counter:
    lines = ptx.splitlines()
    files = {m.group(1): m.group(2) for m in (re.match(r"\.file\s+(\d+)\s+\"(.*?)\"", s.strip()) for s in lines) if m}
    counts, current = collections.Counter(), None
    for raw in lines:
        s = raw.strip()
        m = re.match(r"\.loc\s+(\d+)\s+(\d+)", s)
        if m:
            if files.get(m.group(1), "").endswith("elastic.py"):
                current = int(m.group(2))
            else:
                inlined = re.search(r"inlined_at\s+(\d+)\s+(\d+)", s)
                if inlined and files.get(inlined.group(1), "").endswith("elastic.py"):
                    current = int(inlined.group(2))
            continue
        if not s or s.startswith((".", "//", "{", "}")) or s.endswith(":"):
            continue
        counts[current] += 1
    return counts


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--arch", type=int, default=90)
    ap.add_argument("--arithmetic", default="float32", choices=("float32", "float64"))
    ap.add_argument("--top", type=int, default=40)
    args = ap.parse_args(argv)
    import warp as wp

    wp.config.quiet = True
    wp.config.lineinfo = True
    wp.init()
    import dftl_warp as dw

    pts = np.c_[np.arange(4) * 0.01, np.zeros(4), np.zeros(4)]
    model = dw.Model.from_strands(pts, [4], device="cpu", widths=80e-6)
    solver = dw.make_solver(model, "elastic", compute_precision=args.arithmetic)
    with tempfile.TemporaryDirectory() as tmp:
        paths = wp.compile_aot_module(solver._kernels[0].module, arch=args.arch, module_dir=tmp, use_ptx=True)
        ptx = Path(next(p for p in paths if str(p).endswith(".ptx"))).read_text(errors="replace")
    counts = line_counts(ptx)
    source = KERNEL.read_text().splitlines()
    print(f"{sum(counts.values())} PTX instructions (sm_{args.arch}, {args.arithmetic} arithmetic)")
    for line, n in counts.most_common(args.top):
        text = source[line - 1].strip()[:90] if line else "(kernel entry, no line)"
        print(f"{n:6d}  L{line}: {text}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
