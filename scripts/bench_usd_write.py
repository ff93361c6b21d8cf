"""Writing speed of the USD writer: points, velocities and extent authored and saved to .usdc.

A 10k-strand groom (32 vertices each, 320k points) over 100 frames, written through
:class:`dftl_warp.output.usd.UsdWriter` as ``dftl-warp simulate`` writes (which now hands over float32): float64 local
arrays in, float32 time samples authored in Sdf change blocks, the crate file saved whenever
``flush_bytes`` of samples have accumulated, renamed into place at the end. Target: >= 10 M points
per second on the CPU machine.

    python scripts/bench_usd_write.py [--out docs/results] [--strands 10000] [--vertices 32] [--frames 100]

``run(out_dir)`` returns the markdown table rows (``HEADER`` has the header); ``scripts/bench.py``
calls it.
"""

from __future__ import annotations

import argparse
import datetime
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent

HEADER = [
    "| case (best of 3) | strands | points / frame | frames | seconds | M points / s | file MiB | RSS growth MiB |",
    "|---|---:|---:|---:|---:|---:|---:|---:|",
]


def _rss_mib() -> float:
    try:
        with open("/proc/self/statm") as f:
            return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 2**20
    except OSError:
        return float("nan")


def _groom(path: Path, strands: int, vertices: int, *, vertex_widths: bool = False) -> None:
    """A BasisCurves groom; widths 0.5 mm (constant) or, with ``vertex_widths``, 0.6 -> 0.2 mm along
    each strand (bench_usd_write_parts.py: the extent padded per vertex)."""
    from pxr import Usd, UsdGeom, Vt

    rng = np.random.default_rng(0)
    roots = rng.normal(size=(strands, 3))
    roots /= np.linalg.norm(roots, axis=1, keepdims=True)
    pts = roots[:, None, :] * (0.1 + 0.005 * np.arange(vertices)[None, :, None])
    stage = Usd.Stage.CreateNew(str(path))
    UsdGeom.SetStageUpAxis(stage, "Y")
    UsdGeom.SetStageMetersPerUnit(stage, 1.0)
    stage.SetStartTimeCode(0)
    stage.SetEndTimeCode(1)
    stage.SetDefaultPrim(UsdGeom.Xform.Define(stage, "/World").GetPrim())
    curves = UsdGeom.BasisCurves.Define(stage, "/World/Hair")
    curves.CreateTypeAttr("linear")
    curves.CreateCurveVertexCountsAttr(Vt.IntArray([vertices] * strands))
    curves.CreatePointsAttr(Vt.Vec3fArray.FromNumpy(pts.reshape(-1, 3).astype(np.float32)))
    if vertex_widths:
        widths = np.linspace(6e-4, 2e-4, vertices, dtype=np.float32)
        curves.CreateWidthsAttr(Vt.FloatArray.FromNumpy(np.tile(widths, strands)))
        curves.SetWidthsInterpolation("vertex")
    else:
        curves.CreateWidthsAttr(Vt.FloatArray([0.0005]))
        curves.SetWidthsInterpolation("constant")
    stage.Save()


def measure(out_dir: Path, *, strands: int, vertices: int, frames: int, flush_bytes: int | None, label: str,
            repeat: int = 3) -> str:
    """Write ``frames`` frames ``repeat`` times; one table row with the fastest run (the machine
    is shared, so slower runs measure other load, not the writer)."""
    runs = [_measure_once(out_dir, strands=strands, vertices=vertices, frames=frames, flush_bytes=flush_bytes)
            for _ in range(repeat)]
    seconds, size, growth = min(runs)
    growth = max(r[2] for r in runs)
    points = strands * vertices
    return (f"| {label} | {strands} | {points} | {frames} | {seconds:.2f} | {points * frames / seconds / 1e6:.1f} "
            f"| {size:.0f} | {growth:.0f} |")


def _measure_once(out_dir: Path, *, strands: int, vertices: int, frames: int, flush_bytes: int | None):
    """(seconds, file MiB, RSS growth MiB) of one run."""
    from dftl_warp.usd.read import read_scene
    from dftl_warp.output.usd import DEFAULT_FLUSH_BYTES, UsdWriter

    out_dir.mkdir(parents=True, exist_ok=True)
    src = out_dir / f"bench_groom_{strands}x{vertices}.usdc"
    if not src.exists():
        _groom(src, strands, vertices)
    scene = read_scene(src)
    base = scene.curves[0].points
    rng = np.random.default_rng(1)
    # distinct data every frame (crate would de-duplicate repeated arrays)
    wiggle = rng.normal(scale=1e-3, size=base.shape)
    velocity = rng.normal(scale=0.1, size=base.shape)
    output = out_dir / "bench_write.usdc"
    rss0 = _rss_mib()
    # only the writer is timed; making each frame's synthetic data (as a solver would) is not
    start = time.perf_counter()
    writer = UsdWriter.create(output, scene, frames=(0, frames - 1),
                              flush_bytes=DEFAULT_FLUSH_BYTES if flush_bytes is None else flush_bytes)
    seconds = time.perf_counter() - start
    points_f, velocities_f = base.copy(), velocity.copy()
    for f in range(frames):
        points_f += wiggle
        velocities_f += 1e-3
        start = time.perf_counter()
        writer.write_frame(f, [(points_f, velocities_f)])
        seconds += time.perf_counter() - start
    start = time.perf_counter()
    writer.commit()
    seconds += time.perf_counter() - start
    growth = _rss_mib() - rss0
    size = output.stat().st_size / 2**20
    output.unlink()
    return seconds, size, growth


def run(out_dir, *, strands: int = 10_000, vertices: int = 32, frames: int = 100) -> list[str]:
    """Markdown table rows (without the header) for the writer benchmark."""
    out_dir = Path(out_dir)
    return [
        measure(out_dir, strands=strands, vertices=vertices, frames=frames, flush_bytes=None,
                label="streaming, save every 4 MiB (default)"),
        measure(out_dir, strands=strands, vertices=vertices, frames=frames, flush_bytes=1,
                label="streaming, save every frame"),
        measure(out_dir, strands=strands, vertices=vertices, frames=frames, flush_bytes=64 << 20,
                label="streaming, save every 64 MiB"),
    ]


def memory_trace(out_dir, *, strands: int = 10_000, vertices: int = 32, frames: int = 100) -> dict:
    """Resident memory (MiB) after each frame, streaming (default) vs. saving only at the end."""
    from dftl_warp.usd.read import read_scene
    from dftl_warp.output.usd import UsdWriter

    out_dir = Path(out_dir)
    src = out_dir / f"bench_groom_{strands}x{vertices}.usdc"
    if not src.exists():
        _groom(src, strands, vertices)
    scene = read_scene(src)
    points = scene.curves[0].points.copy()
    velocity = np.zeros_like(points)
    traces = {}
    for label, flush in (("streaming (save every 4 MiB)", None), ("save only at the end", 1 << 50)):
        kwargs = {} if flush is None else {"flush_bytes": flush}
        writer = UsdWriter.create(out_dir / "trace.usdc", scene, **kwargs)
        rss = []
        for f in range(frames):
            points += 1e-4
            writer.write_frame(f, [(points, velocity + f)])
            rss.append(_rss_mib())
        writer.commit()
        (out_dir / "trace.usdc").unlink()
        traces[label] = np.array(rss) - rss[0]
    return traces


def plot_memory(traces: dict, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6, 3.5))
    for label, rss in traces.items():
        ax.plot(np.arange(len(rss)), rss, label=label)
    ax.set_xlabel("frames written")
    ax.set_ylabel("resident memory growth (MiB)")
    ax.set_title("USD writer memory, 10k strands x 32 points per frame")
    ax.grid(alpha=0.3)
    ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def machine() -> str:
    cpu = platform.processor() or platform.machine()
    try:
        cpu = next(line.split(":", 1)[1].strip() for line in open("/proc/cpuinfo") if line.startswith("model name"))
    except (OSError, StopIteration):
        pass
    return f"{cpu}, {os.cpu_count()} cores, Python {platform.python_version()}"


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default=str(ROOT / "docs" / "results"), help="folder for the markdown table")
    parser.add_argument("--strands", type=int, default=10_000)
    parser.add_argument("--vertices", type=int, default=32)
    parser.add_argument("--frames", type=int, default=100)
    parser.add_argument("--no-plot", action="store_true", help="skip the memory trace and its plot")
    args = parser.parse_args(argv)
    from pxr import Usd

    load = os.getloadavg()
    with tempfile.TemporaryDirectory(prefix="bench_usd_write_") as tmp:
        rows = run(tmp, strands=args.strands, vertices=args.vertices, frames=args.frames)
        traces = None if args.no_plot else memory_trace(tmp, strands=args.strands, vertices=args.vertices,
                                                        frames=args.frames)
    try:
        commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=ROOT, capture_output=True,
                                text=True).stdout.strip()
    except OSError:
        commit = "?"
    lines = [
        f"Command: `python scripts/bench_usd_write.py --strands {args.strands} --vertices {args.vertices} "
        f"--frames {args.frames}`  ",
        f"Machine: {machine()}; usd-core {'.'.join(map(str, Usd.GetVersion()))}; "
        f"load average before the run {load[0]:.2f}  ",
        f"Date: {datetime.datetime.now(datetime.timezone.utc):%Y-%m-%d %H:%M} UTC, commit {commit}",
        "",
        *HEADER,
        *rows,
        "",
    ]
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    if traces is not None:
        plot_memory(traces, out / "usd_write_memory.png")
        lines += [f"Memory growth after {args.frames} frames: "
                  + ", ".join(f"{k}: {v[-1]:.0f} MiB" for k, v in traces.items())
                  + " (plot: usd_write_memory.png)", ""]
    (out / "bench_usd_write.md").write_text("\n".join(lines))
    print("\n".join(lines))
    print(f"wrote {out / 'bench_usd_write.md'}", file=sys.stderr)


if __name__ == "__main__":
    main()
