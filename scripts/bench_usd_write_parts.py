"""Where the USD writer's time goes per frame, for large grooms: the writer alone, on the CPU.

For each groom size (default 20k, 50k and 200k strands x 32 points, per-vertex widths) the script

1. writes ``--frames`` frames through :class:`dftl_warp.output.usd.UsdWriter` exactly as
   ``dftl-warp simulate`` does with a one-layer output (float32 (N, 3) points and velocities per prim,
   views of the host buffers the simulator fills; every frame's data differs) and reports per frame
   the time in ``write_frame`` (authoring) and in the saves (``flush``), and ``commit`` once;
2. times the same frame's work step by step with the building blocks the writer uses: numpy ->
   ``Vt.Vec3fArray`` (:func:`dftl_warp.output.vtarrays.vec3f_array`, or ``Vt.Vec3fArray.FromBuffer``
   where that module does not exist yet: the code before it), the extent
   (``UsdGeom.Curves.ComputeExtent`` with the widths), ``Sdf.Layer.SetTimeSample`` in one
   ``Sdf.ChangeBlock``, and ``Sdf.Layer.Save`` of the frame's samples.

The device -> host copy is not part of it: on the CPU device the simulator hands the writer views of
its own arrays (no copy); on a GPU it is one pinned copy that overlaps the next frame's simulation.

    python scripts/bench_usd_write_parts.py [--strands 20000 50000 200000] [--vertices 32] [--frames 8]
        [--out docs/results] [--profile]

Writes ``bench_usd_write_parts.md`` (the table, command, machine, date, and the checkout and commit
whose writer was timed: the ``dftl_warp`` that Python imports, so another checkout's ``.venv/bin/python``
times that checkout's writer) into ``--out``;
``--profile`` also prints cProfile's top functions for one end-to-end run of the largest groom.
"""

from __future__ import annotations

import argparse
import datetime
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_usd_write import _groom, machine  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent

HEADER = [
    "| strands | points / frame | write_frame ms | save ms | total ms / frame | CPU ms / frame | commit ms "
    "| to Vt ms (x2) | extent ms | SetTimeSample ms | Save ms |",
    "|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|",
]


def to_vt():
    """The writer's numpy -> Vt.Vec3fArray conversion (FromBuffer before vtarrays existed)."""
    try:
        from dftl_warp.output.vtarrays import vec3f_array
    except ImportError:
        from pxr import Vt

        return Vt.Vec3fArray.FromBuffer, "Vt.Vec3fArray.FromBuffer"
    return vec3f_array, "vtarrays.vec3f_array"


def frames_data(base: np.ndarray, frames: int):
    """Per frame float32 (points, velocities), each frame's own values, in two reused buffers (as
    the simulator's host buffers are)."""
    rng = np.random.default_rng(1)
    wiggle = rng.normal(scale=1e-3, size=base.shape).astype(np.float32)
    points = base.astype(np.float32)
    velocities = rng.normal(scale=0.1, size=base.shape).astype(np.float32)
    for _ in range(frames):
        points += wiggle
        velocities += np.float32(1e-3)
        yield points, velocities


def end_to_end(folder: Path, scene, frames: int) -> dict:
    """Seconds in write_frame (without its saves), in saves, and in commit, summed over the frames,
    and the process's CPU seconds in write_frame (its saves included: all threads)."""
    from dftl_warp.output.usd import UsdWriter

    output = folder / "bench_parts.usdc"
    writer = UsdWriter.create(output, scene, frames=(0, frames - 1))
    writing = cpu = 0.0
    for f, (p, v) in enumerate(frames_data(scene.curves[0].points, frames)):
        start, start_cpu = time.perf_counter(), time.process_time()
        writer.write_frame(f, [(p, v)])
        writing += time.perf_counter() - start
        cpu += time.process_time() - start_cpu
    saving = writer.seconds_saving
    start = time.perf_counter()
    writer.commit()
    commit = time.perf_counter() - start - (writer.seconds_saving - saving)
    output.unlink()
    return {"write_frame": writing - saving, "save": writer.seconds_saving, "commit": commit, "cpu": cpu}


def parts(folder: Path, scene, frames: int) -> dict:
    """Seconds per step summed over the frames, the frame's work done step by step."""
    from pxr import Sdf, UsdGeom, Vt

    convert, _ = to_vt()
    c = scene.curves[0]
    widths = Vt.FloatArray.FromNumpy(np.ascontiguousarray(c.widths, dtype=np.float32))
    layer = Sdf.Layer.CreateNew(str(folder / "bench_parts_steps.usdc"))
    prim = Sdf.CreatePrimInLayer(layer, c.path)
    prim.specifier = Sdf.SpecifierOver
    paths = []
    for name, kind in (("points", Sdf.ValueTypeNames.Point3fArray), ("velocities", Sdf.ValueTypeNames.Vector3fArray),
                       ("extent", Sdf.ValueTypeNames.Float3Array)):
        Sdf.AttributeSpec(prim, name, kind)
        paths.append(prim.path.AppendProperty(name))
    layer.Save()
    out = dict.fromkeys(("to_vt", "extent", "set", "save"), 0.0)
    for f, (p, v) in enumerate(frames_data(c.points, frames)):
        t0 = time.perf_counter()
        vp, vv = convert(p), convert(v)
        t1 = time.perf_counter()
        e = UsdGeom.Curves.ComputeExtent(vp, widths)
        t2 = time.perf_counter()
        with Sdf.ChangeBlock():
            for path, value in zip(paths, (vp, vv, e)):
                layer.SetTimeSample(path, float(f), value)
        t3 = time.perf_counter()
        del vp, vv, e
        layer.Save()
        t4 = time.perf_counter()
        for key, seconds in zip(out, (t1 - t0, t2 - t1, t3 - t2, t4 - t3)):
            out[key] += seconds
    del layer
    (folder / "bench_parts_steps.usdc").unlink()
    return out


def row(folder: Path, strands: int, vertices: int, frames: int, repeat: int) -> str:
    """One table row: the best (shortest) of ``repeat`` runs of each kind, in ms per frame."""
    from dftl_warp.usd.read import read_scene

    src = folder / f"bench_groom_{strands}x{vertices}.usdc"
    _groom(src, strands, vertices, vertex_widths=True)
    scene = read_scene(src)
    src.unlink()
    ends = [end_to_end(folder, scene, frames) for _ in range(repeat)]
    steps = [parts(folder, scene, frames) for _ in range(repeat)]
    ms = {k: 1e3 * min(r[k] for r in ends) / frames for k in ("write_frame", "save")}
    commit = 1e3 * min(r["commit"] for r in ends)
    best = min(ends, key=lambda r: r["write_frame"] + r["save"])
    total = 1e3 * (best["write_frame"] + best["save"]) / frames
    cpu = 1e3 * min(r["cpu"] for r in ends) / frames
    st = {k: 1e3 * min(r[k] for r in steps) / frames for k in steps[0]}
    return (f"| {strands} | {strands * vertices} | {ms['write_frame']:.1f} | {ms['save']:.1f} | {total:.1f} "
            f"| {cpu:.1f} "
            f"| {commit:.1f} | {st['to_vt']:.1f} | {st['extent']:.1f} | {st['set']:.2f} | {st['save']:.1f} |")


def profile(folder: Path, strands: int, vertices: int, frames: int) -> None:
    import cProfile
    import pstats

    from dftl_warp.usd.read import read_scene

    src = folder / f"bench_groom_{strands}x{vertices}.usdc"
    _groom(src, strands, vertices, vertex_widths=True)
    scene = read_scene(src)
    prof = cProfile.Profile()
    prof.runcall(end_to_end, folder, scene, frames)
    pstats.Stats(prof).sort_stats("tottime").print_stats(12)


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--strands", type=int, nargs="+", default=[20_000, 50_000, 200_000])
    parser.add_argument("--vertices", type=int, default=32)
    parser.add_argument("--frames", type=int, default=8)
    parser.add_argument("--repeat", type=int, default=3, help="runs of each kind; the fastest is reported")
    parser.add_argument("--out", default=str(ROOT / "docs" / "results"), help="folder for the markdown table")
    parser.add_argument("--profile", action="store_true", help="print cProfile's top functions (largest groom)")
    args = parser.parse_args(argv)
    from pxr import Usd

    load = os.getloadavg()
    with tempfile.TemporaryDirectory(prefix="bench_usd_write_parts_") as tmp:
        rows = [row(Path(tmp), s, args.vertices, args.frames, args.repeat) for s in args.strands]
        if args.profile:
            profile(Path(tmp), max(args.strands), args.vertices, args.frames)
    import dftl_warp

    code = Path(dftl_warp.__file__).resolve().parent.parent   # the checkout whose writer was timed
    commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=code, capture_output=True,
                            text=True).stdout.strip() or "?"
    dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no", "dftl_warp"], cwd=code,
                           capture_output=True, text=True).stdout.strip()
    lines = [
        f"Command: `python scripts/bench_usd_write_parts.py --strands {' '.join(map(str, args.strands))} "
        f"--vertices {args.vertices} --frames {args.frames} --repeat {args.repeat}`  ",
        f"Machine: {machine()}; usd-core {'.'.join(map(str, Usd.GetVersion()))}; "
        f"load average before the run {load[0]:.2f}  ",
        f"Date: {datetime.datetime.now(datetime.timezone.utc):%Y-%m-%d %H:%M} UTC; writer: {code}, commit {commit}"
        + (" (with uncommitted changes)" if dirty else "") + f"; numpy -> Vt: {to_vt()[1]}",
        "",
        *HEADER,
        *rows,
        "",
    ]
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "bench_usd_write_parts.md").write_text("\n".join(lines))
    print("\n".join(lines))
    print(f"wrote {out / 'bench_usd_write_parts.md'}", file=sys.stderr)


if __name__ == "__main__":
    main()
