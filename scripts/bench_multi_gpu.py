#!/usr/bin/env python3
"""Multi-device speed-up: one groom split across the devices of one host (``--device A,B,...``).

Sections (``--sections``, comma separated; default both):

- ``compute``  : device-built straight grooms (:func:`dftl_warp.core.synthetic.uniform_groom`) of each
                 ``--strands`` size, the strands split evenly over the first k devices for k = 1, 2,
                 4, ... up to all of ``--devices``; a frame is ``--substeps`` substeps (fused kernels
                 on CUDA, CUDA graphs); every part is launched before any is waited for. Measured:
                 frames/s with one synchronisation at the end ("async") and with one per frame
                 ("per frame", as a writer needs), the speed-up over k = 1, and whether the split
                 result equals the single-device one bit for bit.
- ``simulate`` : the frame loop of ``dftl-warp simulate`` (:class:`dftl_warp.simulation.simulate.Simulation`)
                 on a generated USD groom of ``--usd-strands`` strands under an animated transform:
                 ``advance()`` alone and ``advance()`` + ``samples()`` (gathering every point to the
                 host in local space), single device against all of ``--devices``; identical
                 samples checked.
- ``hairhair`` : as ``simulate`` with hair-hair interaction on (``dftl:hairHair``): the parts step
                 in lockstep and exchange the grid every substep (not bitwise: the largest
                 difference from one device is reported, stage units). Not in the default sections.
- ``elastic``  : as ``simulate`` with widths of 80 um hair on the groom, so that it runs as elastic rods
                 (the default solver for a prim with widths; float64 arithmetic, the default): each
                 part has its own elastic solver, identical samples checked. Not in the default sections.

Results go to ``--out``: results.json, bench_multi_gpu.md, speedup.png.

    python scripts/bench_multi_gpu.py --devices cuda:0,cuda:1 --out OUT
    python scripts/bench_multi_gpu.py --devices cuda:0,cuda:1,cuda:2,cuda:3 --out OUT
    python scripts/bench_multi_gpu.py --devices cpu,cpu --strands 8192 --usd-strands 2000 --out OUT  # smoke test
    python scripts/bench_multi_gpu.py --devices cuda:0,cuda:1 --sections simulate,hairhair --out OUT
    python scripts/bench_multi_gpu.py --devices cuda:0,cuda:1 --sections simulate,elastic --out OUT
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import platform
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import warp as wp

#: precision of the simulate-loop sections (--precision)
PRECISION = "float32"


from dftl_warp.simulation.multi_device import parse_devices  # noqa: E402
from dftl_warp.solvers import make_solver  # noqa: E402
from dftl_warp.core.synthetic import uniform_groom  # noqa: E402

GRAVITY = (0.0, -9.81, 0.0)
#: uniform_groom places strand s at z = spacing * (s % 1024): parts of a multiple of 1024 strands
#: hold exactly the strands of the whole groom
STRAND_QUANTUM = 1024


def device_counts(n: int) -> list[int]:
    ks, k = [], 1
    while k < n:
        ks.append(k)
        k *= 2
    return ks + [n]


def strand_major(model, positions: np.ndarray) -> np.ndarray:
    """Positions (S, V, 3) whatever the layout (uniform grooms: one vertex count), gathered
    through the layout's slots (an interleaved layout's arrays also hold the other fields)."""
    V = int(model.counts[0])
    lay = model.layout
    slots = lay.strand_base[:, None] + np.arange(V)[None, :] * lay.strand_stride[:, None]
    return positions[slots]


def bench_compute(devices, strands, vertices, substeps, frames, repeats=3):
    rows = []
    dt = 1.0 / (24.0 * substeps)
    for total in strands:
        quantum = STRAND_QUANTUM * len(devices)
        total = -(-int(total) // quantum) * quantum
        reference, base = None, None
        for k in device_counts(len(devices)):
            used = devices[:k]
            parts = []
            for d in used:
                with wp.ScopedDevice(d):
                    model, state = uniform_groom(total // k, vertices, device=d)
                    solver = make_solver(model, "dftl", gravity=GRAVITY)
                    parts.append((d, model, state, solver, model.control()))

            def frame():
                for d, model, state, solver, control in parts:
                    with wp.ScopedDevice(d):
                        solver.advance(state, control, dt, substeps)

            def sync():
                for d in dict.fromkeys(used):
                    wp.synchronize_device(d)

            frame()  # compile, capture graphs
            sync()
            asynchronous, per_frame = [], []
            for _ in range(repeats):
                t = time.perf_counter()
                for _ in range(frames):
                    frame()
                sync()
                asynchronous.append(time.perf_counter() - t)
                t = time.perf_counter()
                for _ in range(frames):
                    frame()
                    sync()
                per_frame.append(time.perf_counter() - t)
            # same number of frames from rest for the bitwise check
            result = np.concatenate([strand_major(m, s.positions.numpy()) for _, m, s, _, _ in parts])
            if reference is None:
                reference = result
            identical = bool(reference.tobytes() == result.tobytes())
            row = {
                "strands": total, "vertices": vertices, "particles": total * vertices, "devices": k,
                "device_list": ",".join(used), "substeps": substeps, "frames": frames,
                "frames_per_s_async": frames / min(asynchronous),
                "frames_per_s_per_frame_sync": frames / min(per_frame),
                "particle_steps_per_s": frames * substeps * total * vertices / min(asynchronous),
                "identical_to_one_device": identical,
            }
            base = base or row
            row["speedup_async"] = row["frames_per_s_async"] / base["frames_per_s_async"]
            row["speedup_per_frame_sync"] = row["frames_per_s_per_frame_sync"] / base["frames_per_s_per_frame_sync"]
            rows.append(row)
            print(f"compute {total} strands x {vertices} on {k} device(s): {row['frames_per_s_async']:.1f} frames/s "
                  f"(x{row['speedup_async']:.2f}), per-frame sync {row['frames_per_s_per_frame_sync']:.1f} "
                  f"(x{row['speedup_per_frame_sync']:.2f}), identical {identical}", flush=True)
            del parts, result
    return rows


def groom_usd(path: Path, strands: int, vertices: int, frames: int, hair_hair: bool = False,
              widths: float | None = None) -> Path:
    """A .usdc with one BasisCurves prim of straight strands under a turning Xform (cm, Y up);
    ``hair_hair``: ``dftl:hairHair`` on (default cell size) on the Xform, made the default prim;
    ``widths`` (cm): constant widths, which make the prim elastic rods."""
    from pxr import Gf, Usd, UsdGeom, Vt

    stage = Usd.Stage.CreateNew(str(path))
    UsdGeom.SetStageUpAxis(stage, "Y")
    UsdGeom.SetStageMetersPerUnit(stage, 0.01)
    stage.SetTimeCodesPerSecond(24)
    stage.SetStartTimeCode(1)
    stage.SetEndTimeCode(frames)
    head = UsdGeom.Xform.Define(stage, "/Head")
    turn = head.AddRotateYOp()
    turn.Set(0.0, 1)
    turn.Set(60.0, frames)
    head.AddTranslateOp().Set(Gf.Vec3d(0, 160, 0))
    if hair_hair:
        from pxr import Sdf

        stage.SetDefaultPrim(head.GetPrim())
        head.GetPrim().CreateAttribute("dftl:hairHair", Sdf.ValueTypeNames.Bool, custom=True).Set(True)
    side = int(np.ceil(np.sqrt(strands)))
    roots = np.stack(np.meshgrid(np.arange(side), np.arange(side)), -1).reshape(-1, 2)[:strands] * 0.05
    points = np.zeros((strands, vertices, 3), dtype=np.float32)
    points[:, :, 0] = roots[:, None, 0]
    points[:, :, 2] = roots[:, None, 1]
    points[:, :, 1] = -0.8 * np.arange(vertices)[None, :]
    curves = UsdGeom.BasisCurves.Define(stage, "/Head/Hair")
    curves.CreateTypeAttr("linear")
    curves.CreateCurveVertexCountsAttr(Vt.IntArray.FromNumpy(np.full(strands, vertices, dtype=np.int32)))
    curves.CreatePointsAttr(Vt.Vec3fArray.FromNumpy(points.reshape(-1, 3)))
    if widths is not None:
        curves.CreateWidthsAttr(Vt.FloatArray([float(widths)]))
        curves.SetWidthsInterpolation("constant")
    stage.GetRootLayer().Save()
    return path


def bench_simulate(devices, strands, vertices, substeps, frames, hair_hair=False, elastic=False):
    from dftl_warp.simulation.simulate import Simulation, SimulationOptions
    from dftl_warp.usd.read import read_scene

    with tempfile.TemporaryDirectory() as tmp:
        path = groom_usd(Path(tmp) / "groom.usdc", strands, vertices, frames + 2, hair_hair,
                         widths=80e-4 if elastic else None)
        scene = read_scene(str(path))
    rows, outputs = [], {}
    for device in dict.fromkeys([devices[0], ",".join(devices)]):
        sim = Simulation(scene, SimulationOptions(device=device, substeps=substeps, precision=PRECISION), 1)
        solvers = {g.settings.solver for g in sim.groups}
        if solvers != {"elastic" if elastic else "dftl"}:
            raise SystemExit(f"the groom runs {solvers}, not what the section measures")
        sim.advance()  # compile, capture graphs
        sim.samples()
        t_advance = t_samples = 0.0
        for _ in range(frames):
            t = time.perf_counter()
            sim.advance()
            for d in dict.fromkeys(parse_devices(device)):
                wp.synchronize_device(d)
            t_advance += time.perf_counter() - t
            t = time.perf_counter()
            samples = sim.samples()
            t_samples += time.perf_counter() - t
        outputs[device] = [(p.copy(), v.copy()) for p, v in samples]  # CPU samples may be views
        rows.append({
            "device_list": device, "devices": len(parse_devices(device)), "strands": strands, "vertices": vertices,
            "substeps": substeps, "frames": frames,
            "advance_frames_per_s": frames / t_advance,
            "advance_and_samples_frames_per_s": frames / (t_advance + t_samples),
            "samples_seconds_per_frame": t_samples / frames,
        })
        what = " (hair-hair)" if hair_hair else " (elastic)" if elastic else ""
        print(f"simulate {strands} strands{what} on {device}: advance {rows[-1]['advance_frames_per_s']:.1f} frames/s, "
              f"with samples {rows[-1]['advance_and_samples_frames_per_s']:.1f} frames/s", flush=True)
    one = outputs[devices[0]]
    for row in rows:
        got = outputs[row["device_list"]]
        row["identical_to_one_device"] = all(
            p.tobytes() == q.tobytes() and v.tobytes() == w.tobytes() for (p, v), (q, w) in zip(got, one))
        row["max_abs_difference"] = max(float(np.max(np.abs(p - q), initial=0.0)) for (p, _), (q, _) in zip(got, one))
        row["speedup_advance"] = row["advance_frames_per_s"] / rows[0]["advance_frames_per_s"]
        row["speedup_with_samples"] = row["advance_and_samples_frames_per_s"] / rows[0]["advance_and_samples_frames_per_s"]
    return rows


def machine_line(devices):
    names = ", ".join(f"{wp.get_device(d).alias} {wp.get_device(d).name}" for d in dict.fromkeys(devices))
    cpu = platform.processor() or platform.machine()
    try:
        with open("/proc/cpuinfo") as f:
            cpu = next(line.split(":", 1)[1].strip() for line in f if line.startswith("model name"))
    except (OSError, StopIteration):
        pass
    return f"{names}; host CPU {cpu}, {os.cpu_count()} cores; Warp {wp.__version__}"


def to_markdown(res) -> str:
    lines = [f"### {res['machine']}", "", f"Date {res['date']}. Command: `{res['command']}`", ""]
    if res.get("compute"):
        lines += ["Device-built grooms (fused substeps on CUDA); speed-up over one device "
                  "(async: one synchronisation at the end; per frame: one per frame):", "",
                  "| strands x vertices | devices | frames/s async | speed-up | frames/s per-frame sync | speed-up | particle-steps/s | identical |",
                  "|---|---:|---:|---:|---:|---:|---:|---|"]
        for r in res["compute"]:
            lines.append(f"| {r['strands']} x {r['vertices']} | {r['devices']} | {r['frames_per_s_async']:.1f} | "
                         f"{r['speedup_async']:.2f} | {r['frames_per_s_per_frame_sync']:.1f} | "
                         f"{r['speedup_per_frame_sync']:.2f} | {r['particle_steps_per_s']:.3g} | "
                         f"{r['identical_to_one_device']} |")
        lines.append("")
    for key, title in (("simulate", "Frame loop of `dftl-warp simulate` (USD groom, animated transform):"),
                       ("hairhair", "The same with hair-hair interaction (grid exchanged every substep; "
                                    "max |difference| from one device in stage units):"),
                       ("elastic", "The same groom as elastic rods of 80 um hair (float64 arithmetic):")):
        if not res.get(key):
            continue
        lines += [title, "",
                  "| devices | strands x vertices | advance frames/s | speed-up | advance + samples frames/s | speed-up | samples s/frame | identical | max diff |",
                  "|---|---|---:|---:|---:|---:|---:|---|---:|"]
        for r in res[key]:
            lines.append(f"| {r['device_list']} | {r['strands']} x {r['vertices']} | {r['advance_frames_per_s']:.1f} | "
                         f"{r['speedup_advance']:.2f} | {r['advance_and_samples_frames_per_s']:.1f} | "
                         f"{r['speedup_with_samples']:.2f} | {r['samples_seconds_per_frame']:.3f} | "
                         f"{r['identical_to_one_device']} | {r['max_abs_difference']:.2g} |")
        lines.append("")
    return "\n".join(lines)


def plot(res, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6, 4))
    sizes = sorted({r["strands"] for r in res["compute"]})
    for size in sizes:
        rows = [r for r in res["compute"] if r["strands"] == size]
        ax.plot([r["devices"] for r in rows], [r["speedup_async"] for r in rows], "o-",
                label=f"{size:,} strands x {rows[0]['vertices']}")
    top = max(r["devices"] for r in res["compute"])
    ax.plot([1, top], [1, top], "k:", label="ideal")
    ax.set_xlabel("devices")
    ax.set_ylabel("speed-up over one device")
    ax.set_title(res["machine"].split(";")[0][:60], fontsize=8)
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=120)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--devices", default="cuda:0,cuda:1", help="comma-separated devices (a device may repeat)")
    ap.add_argument("--sections", default="compute,simulate")
    ap.add_argument("--strands", default="262144,1048576,4194304", help="groom sizes for 'compute' (comma list)")
    ap.add_argument("--vertices", type=int, default=32)
    ap.add_argument("--substeps", type=int, default=8)
    ap.add_argument("--frames", type=int, default=100)
    ap.add_argument("--usd-strands", type=int, default=200000, help="strands of the 'simulate' groom")
    ap.add_argument("--usd-frames", type=int, default=20)
    ap.add_argument("--precision", default="float32", choices=("float32", "float64"),
                    help="precision of the simulate and hairhair sections (default float32)")
    ap.add_argument("--out", default=None, help="folder for results.json, bench_multi_gpu.md, speedup.png")
    args = ap.parse_args(argv)
    global PRECISION
    PRECISION = args.precision
    wp.config.log_level = wp.LOG_WARNING
    wp.init()
    devices = [str(wp.get_device(d)) for d in parse_devices(args.devices)]
    sections = set(args.sections.split(","))
    res = {"devices": devices, "machine": machine_line(devices), "date": datetime.date.today().isoformat(),
           "warp": wp.__version__,
           "command": "python scripts/bench_multi_gpu.py " + " ".join(argv if argv is not None else sys.argv[1:])}
    if "compute" in sections:
        res["compute"] = bench_compute(devices, [int(s) for s in args.strands.split(",")], args.vertices,
                                       args.substeps, args.frames)
    if "simulate" in sections:
        res["simulate"] = bench_simulate(devices, args.usd_strands, args.vertices, args.substeps, args.usd_frames)
    if "hairhair" in sections:
        res["hairhair"] = bench_simulate(devices, args.usd_strands, args.vertices, args.substeps, args.usd_frames,
                                         hair_hair=True)
    if "elastic" in sections:
        res["elastic"] = bench_simulate(devices, args.usd_strands, args.vertices, args.substeps, args.usd_frames,
                                        elastic=True)
    md = to_markdown(res)
    print()
    print(md)
    if args.out:
        out = Path(args.out)
        out.mkdir(parents=True, exist_ok=True)
        (out / "results.json").write_text(json.dumps(res, indent=1))
        (out / "bench_multi_gpu.md").write_text(md + "\n")
        if res.get("compute"):
            try:
                plot(res, out / "speedup.png")
            except ImportError:
                print("matplotlib not available: no speedup.png", file=sys.stderr)


if __name__ == "__main__":
    main()
