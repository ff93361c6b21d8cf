#!/usr/bin/env python3
"""Registers and stack frame (local memory: spills and local arrays) of the step kernels of
``bench_features.py``'s scenes and their features two at a time, compiled ahead of time for a
CUDA architecture with Warp's NVRTC: no GPU needed.

Each row builds its scene's solver on the CPU device (a 4-particle groom: the kernels do not depend
on the groom's size), compiles the modules of the kernels its step launches for ``--arch``
(``wp.compile_aot_module``, to a cubin) and reads, from the cubin's ``.nv.info`` section, each
kernel's register count (``EIATTR_REGCOUNT``) and frame size (``EIATTR_FRAME_SIZE``, bytes per
thread). A frame above zero means local memory, whose traffic the GPU pays beside the State's.

    python scripts/kernel_resources.py --arch 90
    python scripts/kernel_resources.py --only "elastic: gravity" "elastic: all" --elastic-caps 128 168 0
"""

from __future__ import annotations

import argparse
import contextlib
import struct
import sys
import tempfile
from pathlib import Path

import numpy as np
import warp as wp

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_features import ELASTIC, G  # noqa: E402

import dftl_warp as dw  # noqa: E402
from dftl_warp import features as F  # noqa: E402
from dftl_warp.kernels.solvers import elastic as elastic_kernels  # noqa: E402

#: EIATTR codes of the cubin's .nv.info section (each an SVAL of a symbol index and a value)
EIATTR_FRAME_SIZE = 0x11
EIATTR_REGCOUNT = 0x2F


def cubin_resources(path) -> dict:
    """``{function name: {"registers": n, "frame": bytes}}`` from a cubin (ELF64)."""
    b = Path(path).read_bytes()
    shoff, = struct.unpack_from("<Q", b, 0x28)
    shentsize, shnum, shstrndx = struct.unpack_from("<HHH", b, 0x3A)
    secs = [struct.unpack_from("<IIQQQQIIQQ", b, shoff + i * shentsize) for i in range(shnum)]

    def name_at(table_offset, o):
        return b[table_offset + o:b.index(b"\0", table_offset + o)].decode()

    names = {name_at(secs[shstrndx][4], s[0]): s for s in secs}
    symtab, strtab = names[".symtab"], names[".strtab"]
    symbols = [name_at(strtab[4], struct.unpack_from("<I", b, symtab[4] + i * 24)[0])
               for i in range(symtab[5] // 24)]
    info = names[".nv.info"]
    out = {}
    p, end = info[4], info[4] + info[5]
    while p < end:
        fmt, attr = b[p], b[p + 1]
        if fmt == 4:  # EIFMT_SVAL: size, payload
            size, = struct.unpack_from("<H", b, p + 2)
            if size == 8 and attr in (EIATTR_REGCOUNT, EIATTR_FRAME_SIZE):
                sym, value = struct.unpack_from("<II", b, p + 4)
                key = "registers" if attr == EIATTR_REGCOUNT else "frame"
                out.setdefault(symbols[sym], {})[key] = value
            p += 4 + size
        else:
            p += 4
    return {k: v for k, v in out.items() if "registers" in v}


def rows():
    """(name, features, solver options) of the scenes: each feature of the production scene on
    its own, two at a time, all three, with DFTL and with elastic strands (float32 arithmetic)."""
    sphere_mesh = F.TriangleMesh(points=np.array([[0, 0, 0], [1, 0, 0], [0, 0, 1.0]]) - 5.0,
                                 indices=np.array([[0, 1, 2]]), sdf=True, sdf_cell=0.05)

    def field():
        return F.Colliders([sphere_mesh])

    def noise():
        return [F.Drag(1.0), F.Wind(velocity=(1.0, 0, 0), noise_amplitude=0.5)]

    def hh():
        return F.HairHair(cell_size=0.01)

    sets = [("gravity", lambda: []), ("field", lambda: [field()]), ("hair-hair", lambda: [hh()]),
            ("curl-noise wind", noise), ("field + hair-hair", lambda: [field(), hh()]),
            ("field + curl-noise wind", lambda: [field(), *noise()]),
            ("hair-hair + curl-noise wind", lambda: [hh(), *noise()]),
            ("all three", lambda: [field(), hh(), *noise()])]
    for solver, extra in (("DFTL", {}), ("elastic", ELASTIC)):
        for name, feats in sets:
            yield f"{solver}: {name}", feats(), extra


@contextlib.contextmanager
def cuda_phases():
    """A solver made on the CPU gets the elastic step's CUDA kernels (one per sweep), as on a GPU."""
    import dftl_warp.solvers.elastic as solver_module

    make = solver_module.elastic_step_kernels
    solver_module.elastic_step_kernels = lambda *a: make(*a[:-1], True)
    try:
        yield
    finally:
        solver_module.elastic_step_kernels = make


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--arch", type=int, default=90, help="CUDA architecture (90: H100, H200)")
    ap.add_argument("--only", nargs="*", default=None, help="rows whose names start with one of these")
    ap.add_argument("--elastic-caps", type=int, nargs="*", default=None,
                    help="compile the elastic rows under each of these CUDA register caps (0: none) instead "
                         "of kernels/solvers/elastic.py's CUDA_MAX_REGISTERS_F32")
    args = ap.parse_args(argv)
    wp.config.quiet = True
    wp.init()
    pts = np.stack([np.zeros(4), -np.arange(4) * 0.01, np.zeros(4)], 1)
    print(f"| scene | kernel | registers | stack frame (B) |\n|---|---|---:|---:|")
    default_cap = dict(elastic_kernels.CUDA_MAX_REGISTERS_F32)
    todo = []
    for name, feats, extra in rows():
        if args.only and not name.startswith(tuple(args.only)):
            continue
        caps = args.elastic_caps if extra.get("solver") == "elastic" and args.elastic_caps else [None]
        todo += [(name if cap is None else f"{name}, cap {cap or 'none'}", feats, extra, cap) for cap in caps]
    with tempfile.TemporaryDirectory() as tmp:
        for name, feats, extra, cap in todo:
            elastic_kernels.CUDA_MAX_REGISTERS_F32.update(
                default_cap if cap is None else dict.fromkeys(default_cap, cap or None))
            elastic_kernels.elastic_kernel.cache_clear()
            model = dw.Model.from_strands(pts, [4], widths=1e-4, features=feats, device="cpu")
            if extra.get("solver", "dftl") == "dftl":
                solver = dw.DFTLSolver(model, gravity=G, fused=False)
            else:
                with cuda_phases():
                    solver = dw.make_solver(model, extra["solver"], gravity=G, **extra.get("solver_options", {}))
            for kernel in solver.kernels():
                if not kernel.key.startswith(("featured_step", "bare_step", "elastic_kernel", "velocity_features",
                                               "grid_splat", "grid_bounds")):
                    continue
                paths = wp.compile_aot_module(kernel.module, arch=args.arch, module_dir=tmp, use_ptx=False)
                for function, r in cubin_resources(paths[0]).items():
                    if function.endswith("_cuda_kernel_forward"):
                        print(f"| {name} | `{kernel.key.split('__')[0]}` | {r['registers']} | {r.get('frame', 0)} |",
                              flush=True)
    elastic_kernels.CUDA_MAX_REGISTERS_F32.update(default_cap)
    elastic_kernels.elastic_kernel.cache_clear()
    return 0


if __name__ == "__main__":
    sys.exit(main())
