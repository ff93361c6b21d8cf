#!/usr/bin/env python3
"""Does saving a crate (.usdc) layer release Python's interpreter lock? N threads against N
processes, each authoring and saving its own independent crate layer of the same size.

If crate saving (and authoring with Sdf) released the GIL, N threads would take about as long as
N processes; if it holds it, N threads take about N times one writer's time.

    python scripts/bench_crate_gil.py --writers 4 --mb 64 --out DIR
"""

from __future__ import annotations

import argparse
import datetime
import json
import multiprocessing as mp
import os
import platform
import statistics
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor, ThreadPoolExecutor
from pathlib import Path

import numpy as np


def frames_of(mb: float, frames: int = 8, seed: int = 0) -> list:
    """``frames`` points arrays (float32, N x 3) of ``mb`` MiB together."""
    n = max(1, int(mb * (1 << 20) / 12 / frames))
    rng = np.random.default_rng(seed)
    return [rng.random((n, 3), dtype=np.float32) for _ in range(frames)]


def write_layer(path: str, arrays: list) -> int:
    """One crate layer holding ``arrays`` as time samples of one points attribute, saved; bytes.
    The arrays are made by the caller and handed over, as the clips writer hands over a chunk
    (a process gets them pickled through its pipe: that cost is part of the measurement)."""
    from pxr import Sdf, Vt

    layer = Sdf.Layer.CreateNew(path)
    prim = Sdf.CreatePrimInLayer(layer, "/Hair")
    prim.specifier = Sdf.SpecifierOver
    Sdf.AttributeSpec(prim, "points", Sdf.ValueTypeNames.Point3fArray)
    attr = Sdf.Path("/Hair.points")
    for f, a in enumerate(arrays):
        layer.SetTimeSample(attr, float(f), Vt.Vec3fArray.FromNumpy(a))
    layer.Save()
    return os.path.getsize(path)


def write_layer_shm(path: str, name: str, shapes: list) -> int:
    """:func:`write_layer` reading its arrays from the shared memory block ``name``."""
    from multiprocessing import shared_memory

    shm = shared_memory.SharedMemory(name=name)
    try:
        arrays, offset = [], 0
        for n in shapes:
            arrays.append(np.ndarray((n, 3), np.float32, shm.buf, offset))
            offset += n * 12
        size = write_layer(path, arrays)
        del arrays
        return size
    finally:
        shm.close()


def _timed_shm(writers: int, data: list, folder: Path, ctx) -> float:
    """Processes that read their chunk from shared memory; the copy into it is timed (the clips
    writer copies every frame anyway, so it costs nothing extra there)."""
    from multiprocessing import shared_memory

    with ProcessPoolExecutor(writers, mp_context=ctx) as pool:
        list(pool.map(write_layer, [str(folder / f"warm{i}.usdc") for i in range(writers)], [frames_of(0.01)] * writers))
        a = time.perf_counter()
        blocks, futures = [], []
        for i in range(writers):
            arrays = data[i]
            shm = shared_memory.SharedMemory(create=True, size=sum(x.nbytes for x in arrays))
            offset = 0
            for x in arrays:
                np.ndarray(x.shape, np.float32, shm.buf, offset)[...] = x
                offset += x.nbytes
            blocks.append(shm)
            futures.append(pool.submit(write_layer_shm, str(folder / f"l{i}.usdc"), shm.name, [len(x) for x in arrays]))
        sizes = [f.result() for f in futures]
        t = time.perf_counter() - a
        for shm in blocks:
            shm.close()
            shm.unlink()
    for p in folder.glob("*.usdc"):
        p.unlink()
    return sum(sizes) / t


def _timed(pool_cls, writers: int, data: list, folder: Path, **kw) -> float:
    with pool_cls(writers, **kw) as pool:
        small = [frames_of(0.01)] * writers
        list(pool.map(write_layer, [str(folder / f"warm{i}.usdc") for i in range(writers)], small))
        a = time.perf_counter()
        sizes = list(pool.map(write_layer, [str(folder / f"l{i}.usdc") for i in range(writers)], data[:writers]))
        t = time.perf_counter() - a
    for p in folder.glob("*.usdc"):
        p.unlink()
    return sum(sizes) / t


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--writers", type=int, nargs="+", default=[1, 2, 4])
    ap.add_argument("--mb", type=float, default=64, help="MiB per layer")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--dir", default=None, help="where the layers go (default: a temporary folder)")
    ap.add_argument("--out", default=None)
    args = ap.parse_args(argv)
    ctx = mp.get_context("spawn")
    rows = []
    with tempfile.TemporaryDirectory(dir=args.dir) as tmp:
        folder = Path(tmp)
        data = [frames_of(args.mb, seed=i) for i in range(max(args.writers))]
        for n in args.writers:
            th = [_timed(ThreadPoolExecutor, n, data, folder) for _ in range(args.repeats)]
            pr = [_timed(ProcessPoolExecutor, n, data, folder, mp_context=ctx) for _ in range(args.repeats)]
            sh = [_timed_shm(n, data, folder, ctx) for _ in range(args.repeats)]
            rows.append({"writers": n, "threads_bytes_per_s": statistics.median(th),
                         "processes_bytes_per_s": statistics.median(pr), "shm_bytes_per_s": statistics.median(sh),
                         "threads_runs": th, "processes_runs": pr, "shm_runs": sh})
    res = {"host": platform.node(), "cpus": os.cpu_count(), "date": datetime.date.today().isoformat(),
           "mb_per_layer": args.mb, "rows": rows}
    lines = [f"Crate layers of {args.mb:g} MiB each, {res['cpus']} CPUs ({res['host']}), {res['date']}, "
             f"median of {args.repeats} (MB/s written, all writers together):", "",
             "| writers | threads | processes (pickled) | processes (shared memory) | best processes / threads |",
             "|---:|---:|---:|---:|---:|"]
    lines += [f"| {r['writers']} | {r['threads_bytes_per_s'] / 1e6:.0f} | {r['processes_bytes_per_s'] / 1e6:.0f} | "
              f"{r['shm_bytes_per_s'] / 1e6:.0f} | "
              f"{max(r['processes_bytes_per_s'], r['shm_bytes_per_s']) / r['threads_bytes_per_s']:.2f} |" for r in rows]
    md = "\n".join(lines)
    print(md)
    if args.out:
        out = Path(args.out)
        out.mkdir(parents=True, exist_ok=True)
        (out / "crate-gil.md").write_text(md + "\n")
        (out / "crate-gil.json").write_text(json.dumps(res, indent=1))


if __name__ == "__main__":
    main()
