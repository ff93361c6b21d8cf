#!/usr/bin/env python3
"""Batch throughput: a small shot list through ``dftl-warp batch`` with 1 and 2 workers.

The shot list is the example scenes (``scenes/``: default head, ponytail, fur ball, chain) at a
few frame ranges and substep counts. Each configuration runs the real command in a fresh output
folder (nothing to skip), timed from process start to exit, after one warm-up run that fills
Warp's kernel cache. Configurations: 1 worker, 2 workers, 2 workers checkpointing every 5 frames
(the cost of checkpoints), and 2 workers resuming the same batch after a SIGKILL half-way.

Results go to ``--out``: results.json and bench_batch.md.

    python scripts/bench_batch.py --out docs/results/batch
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import platform
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent

#: (scene, first, last, substeps)
SHOTS = [
    ("default.usda", 1, 36, 8),
    ("default.usda", 37, 72, 8),
    ("ponytail.usda", 1, 48, 8),
    ("ponytail.usda", 1, 48, 4),
    ("furball.usda", 1, 36, 6),
    ("furball.usda", 37, 72, 6),
    ("chain.usda", 1, 96, 8),
    ("chain.usda", 1, 96, 16),
]


def write_jobs(folder: Path) -> tuple[Path, int]:
    lines = []
    frames = 0
    for k, (scene, first, last, substeps) in enumerate(SHOTS, start=1):
        lines += ["[[job]]", f'name = "sh{k:03d}"', f'input = "{ROOT / "scenes" / scene}"',
                  f'output = "out/sh{k:03d}.usdc"', f"start = {first}", f"end = {last}", f"substeps = {substeps}", ""]
        frames += last - first + 1
    path = folder / "jobs.toml"
    path.write_text("\n".join(lines))
    return path, frames


def command(jobs: Path, *args) -> list[str]:
    return [sys.executable, "-m", "dftl_warp", "batch", str(jobs), "--quiet", *args]


def run(jobs: Path, *args) -> float:
    shutil.rmtree(jobs.parent / "out", ignore_errors=True)
    start = time.perf_counter()
    done = subprocess.run(command(jobs, *args), cwd=jobs.parent, capture_output=True, text=True)
    seconds = time.perf_counter() - start
    if done.returncode != 0:
        raise SystemExit(f"batch failed:\n{done.stdout}\n{done.stderr}")
    return seconds


def run_killed_and_resumed(jobs: Path, *args) -> tuple[float, float]:
    """Wall time until a SIGKILL once half of the jobs are done, then of the rerun."""
    out = jobs.parent / "out"
    shutil.rmtree(out, ignore_errors=True)
    start = time.perf_counter()
    batch = subprocess.Popen(command(jobs, *args), cwd=jobs.parent, stdout=subprocess.DEVNULL,
                             stderr=subprocess.DEVNULL, start_new_session=True)
    while batch.poll() is None and len(list(out.glob("*.usdc"))) < len(SHOTS) // 2:
        time.sleep(0.01)
    os.killpg(batch.pid, signal.SIGKILL)
    batch.wait()
    killed_after = time.perf_counter() - start
    start = time.perf_counter()
    done = subprocess.run(command(jobs, *args), cwd=jobs.parent, capture_output=True, text=True)
    if done.returncode != 0:
        raise SystemExit(f"resumed batch failed:\n{done.stdout}\n{done.stderr}")
    return killed_after, time.perf_counter() - start


def _burn(n: int) -> float:
    t = time.perf_counter()
    total = 0
    for i in range(n):
        total += i
    return time.perf_counter() - t


def cpu_parallelism(n: int = 20_000_000) -> float:
    """How much faster two processes finish two pure-Python loops than one process does (2.0 on
    two free cores): what this machine lets 2 workers gain at best."""
    import multiprocessing as mp

    one = _burn(n)
    with mp.get_context("spawn").Pool(2) as pool:
        pool.map(_burn, [1000, 1000])  # start the processes first
        t = time.perf_counter()
        pool.map(_burn, [n, n])
        two = time.perf_counter() - t
    return 2 * one / two


def machine() -> dict:
    cpu = platform.processor() or platform.machine()
    try:
        with open("/proc/cpuinfo") as f:
            cpu = next(line.split(":", 1)[1].strip() for line in f if line.startswith("model name"))
    except (OSError, StopIteration):
        pass
    return {"cpu": cpu, "cores": os.cpu_count(), "python": platform.python_version(),
            "two_process_speedup": cpu_parallelism()}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", default=None, help="folder for results.json and bench_batch.md")
    ap.add_argument("--repeats", type=int, default=2, help="runs per configuration (the best is kept)")
    args = ap.parse_args(argv)
    res = {"machine": machine(), "date": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="minutes"),
           "command": "python scripts/bench_batch.py " + " ".join(argv if argv is not None else sys.argv[1:]),
           "jobs": len(SHOTS), "shots": SHOTS, "rows": []}
    with tempfile.TemporaryDirectory() as tmp:
        jobs, frames = write_jobs(Path(tmp))
        res["frames"] = frames
        run(jobs, "--workers", "2")  # warm the kernel cache
        configs = [("1 worker", ["--workers", "1"]), ("2 workers", ["--workers", "2"]),
                   ("2 workers, checkpoint every 5 frames", ["--workers", "2", "--checkpoint-frames", "5"])]
        for label, flags in configs:
            seconds = min(run(jobs, *flags) for _ in range(args.repeats))
            res["rows"].append({"configuration": label, "flags": " ".join(flags), "seconds": seconds,
                                "jobs_per_s": len(SHOTS) / seconds, "frames_per_s": frames / seconds})
            print(f"{label}: {seconds:.2f} s, {len(SHOTS) / seconds:.2f} jobs/s, {frames / seconds:.1f} frames/s",
                  flush=True)
        killed, resumed = run_killed_and_resumed(jobs, "--workers", "2", "--checkpoint-frames", "5")
        res["kill"] = {"killed_after_s": killed, "rerun_s": resumed, "total_s": killed + resumed}
        print(f"killed after {killed:.2f} s, rerun {resumed:.2f} s", flush=True)
    m = res["machine"]
    lines = [f"Machine: {m['cpu']}, {m['cores']} cores, no GPU (jobs on the CPU device); Python {m['python']}. "
             f"Date {res['date']}. Command: `{res['command']}`", "",
             f"{res['jobs']} jobs, {res['frames']} frames in all (the example scenes; see the script). "
             f"Two processes of pure-Python work run {m['two_process_speedup']:.2f}x as fast as one here "
             "(2.00 on two free cores): the ceiling for 2 workers.", "",
             "| configuration | wall s | jobs/s | frames/s |", "|---|---:|---:|---:|"]
    for r in res["rows"]:
        lines.append(f"| {r['configuration']} | {r['seconds']:.2f} | {r['jobs_per_s']:.2f} | {r['frames_per_s']:.1f} |")
    k = res["kill"]
    lines += ["", f"SIGKILL once half the jobs were done ({k['killed_after_s']:.2f} s), then the same command: "
              f"{k['rerun_s']:.2f} s more ({k['total_s']:.2f} s in all)."]
    md = "\n".join(lines)
    print()
    print(md)
    if args.out:
        out = Path(args.out)
        out.mkdir(parents=True, exist_ok=True)
        (out / "results.json").write_text(json.dumps(res, indent=1))
        (out / "bench_batch.md").write_text(md + "\n")


if __name__ == "__main__":
    main()
