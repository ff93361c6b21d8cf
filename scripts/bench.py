#!/usr/bin/env python3
"""dftl-warp benchmarks: DFTL step throughput against the device's copy bandwidth.

Sections (``--sections``, comma separated; default all that apply to the device):

- ``copy``    : ``wp.copy`` bandwidth (bytes read + written per second), the ceiling;
- ``step``    : one DFTL step per launch, both layouts x precisions x correction forms, as
                particle-steps/s and as a share of the copy bandwidth counting only the bytes the
                form must move (prior: x, v, correction read + written and rest length read =
                76 B/particle in float32; posterior: 52 B);
- ``numpy``   : the numpy baseline vectorized over strands, same problem, same run;
- ``fused``   : k substeps per launch (state on chip) against the per-step kernel, and a check that
                both give the same result;
- ``scaling`` : per-step throughput from 1k to 4M strands and 8 to 256 particles per strand, a frame
                of substeps captured in a CUDA graph (where launch overhead ends);
- ``memory``  : device bytes per particle, and the largest groom that fits, allocated and stepped.

Every figure is a median of repeats after a warm-up; ratios compare numbers from the same run.
Results go to ``--out`` (results.json, bench-<device>.md, throughput.png).

    python scripts/bench.py --device cpu --out docs/bench/cpu
    python scripts/bench.py --device cuda:0 --out $OUT
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import platform
import statistics
import sys
import time
from pathlib import Path

import numpy as np
import warp as wp


import dftl_warp as dw  # noqa: E402
from dftl_warp.solvers import numpy_baseline as baseline  # noqa: E402
from dftl_warp.kernels.solvers.pipelined import CUDA_LANES  # noqa: E402
from dftl_warp.kernels.core.synthetic import copy_kernel  # noqa: E402
from dftl_warp.core.synthetic import uniform_groom  # noqa: E402

G = (0.0, -9.81, 0.0)
DT = 1.0 / 240.0


def minimal_bytes(precision: str, correction: str) -> int:
    """Bytes per particle a step must move: state read + written, rest length read."""
    w = 4 if precision == "float32" else 8
    vectors = 3 if correction == "prior" else 2
    return 2 * vectors * 3 * w + w


class Timer:
    """Median wall time of ``fn`` (seconds) on ``device``, with device events on CUDA."""

    def __init__(self, device):
        self.device = wp.get_device(device)

    def __call__(self, fn, repeats=5, warmup=1):
        for _ in range(warmup):
            fn()
        wp.synchronize_device(self.device)
        times = []
        for _ in range(repeats):
            if self.device.is_cuda:
                start, end = wp.Event(self.device, enable_timing=True), wp.Event(self.device, enable_timing=True)
                wp.record_event(start)
                fn()
                wp.record_event(end)
                wp.synchronize_event(end)
                times.append(wp.get_event_elapsed_time(start, end) / 1000.0)
            else:
                t = time.perf_counter()
                fn()
                times.append(time.perf_counter() - t)
        return statistics.median(times)


def graph_of(device, fn):
    """``fn`` captured once in a CUDA graph (CPU: ``fn`` itself)."""
    device = wp.get_device(device)
    if not device.is_cuda:
        return fn
    fn()  # load modules before capture
    with wp.ScopedCapture(device=device) as cap:
        fn()
    return lambda: wp.capture_launch(cap.graph)


def bench_copy(device, timer):
    """The ceiling: the faster of ``wp.copy`` (memcpy) and a vec4-per-thread copy kernel."""
    nbytes = (2048 if wp.get_device(device).is_cuda else 64) << 20
    a = wp.zeros(nbytes // 16, dtype=wp.vec4, device=device)
    b = wp.empty_like(a)
    t_memcpy = timer(lambda: wp.copy(b, a), repeats=9)
    kernel = copy_kernel()
    t_kernel = timer(lambda: wp.launch(kernel, dim=a.shape[0], inputs=[a], outputs=[b]), repeats=9)
    return {"bytes": nbytes, "memcpy_Bps": 2 * nbytes / t_memcpy, "kernel_Bps": 2 * nbytes / t_kernel,
            "bandwidth_Bps": 2 * nbytes / min(t_memcpy, t_kernel)}


def step_problem(device):
    return (1 << 20, 32) if wp.get_device(device).is_cuda else (20000, 32)


#: layouts the step section compares: name -> uniform_groom options (``interleaved``: the CUDA
#: default, particle-major with the state vectors interleaved per 32-strand chunk)
STEP_LAYOUTS = {"interleaved": dict(layout="particle-major", interleave=None),  # the default: plain past 2^31 slots
                "particle-major": dict(layout="particle-major", interleave=1),
                "strand-major": dict(layout="strand-major", interleave=1)}


def bench_step(device, timer, copy_bw, strands, count, precisions=("float32", "float64"),
               layouts=("interleaved", "particle-major", "strand-major"), corrections=("prior", "posterior"), steps=10,
               swapped=True):
    """One step per launch through ``advance`` (in place, a CUDA graph of ``steps`` launches); for
    the particle-major layout also with two states swapped between steps (``swapped``)."""
    rows = []
    for precision in precisions:
        for layout in layouts:
            for correction in corrections:
                model, state = uniform_groom(strands, count, device=device, precision=precision,
                                             with_corrections=correction == "prior", **STEP_LAYOUTS[layout])
                solver = dw.DFTLSolver(model, correction=correction, gravity=G, fused=False)
                control = model.control()
                t = timer(lambda: solver.advance(state, control, DT, steps), repeats=5) / steps  # advance uses a CUDA graph
                n = strands * count
                mb = minimal_bytes(precision, correction)
                row = {"precision": precision, "layout": layout, "interleave": model.layout.interleave, "correction": correction,
                       "strands": strands, "particles_per_strand": count, "seconds_per_step": t,
                       "particle_steps_per_s": n / t, "bytes_per_particle": mb,
                       "bandwidth_Bps": n * mb / t, "of_copy": n * mb / t / copy_bw}
                if swapped and layout != "strand-major":
                    # Newton style: step(state_in, state_out), the two states swapped between steps
                    other = state.clone()

                    def run():
                        for k in range(steps):
                            a, b = (state, other) if k % 2 == 0 else (other, state)
                            solver.step(a, b, control, DT)

                    ts = timer(graph_of(device, run), repeats=5) / steps
                    row.update(seconds_per_step_swapped=ts, of_copy_swapped=n * mb / ts / copy_bw)
                    del other
                rows.append(row)
                del model, state, solver
    return rows


def bench_block_dim(device, timer, copy_bw, strands, count, block_dims=(64, 128, 256), steps=10):
    """The float32 prior step launched with several thread-block sizes (Warp's default and the
    kernel's launch bound: 256)."""
    model, state = uniform_groom(strands, count, device=device)
    solver = dw.DFTLSolver(model, gravity=G, fused=False)
    control = model.control()
    m = model
    rows = []
    for block_dim in block_dims:
        def run():
            for k in range(steps):
                wp.launch(solver._kernel, dim=m.num_strands, block_dim=block_dim, device=device,
                          inputs=[m.strand_base, m.strand_stride, m.strand_count, control.root_start,
                                  control.root_end, control.root_deviation_start, control.root_deviation_end,
                                  1.0, m.rest_lengths, solver.gravity, DT, 1.0,
                                  state.positions, state.velocities, state.corrections],
                          outputs=[state.positions, state.velocities, state.corrections])
        t = timer(graph_of(device, run)) / steps
        n = strands * count
        rows.append({"block_dim": block_dim, "particle_steps_per_s": n / t, "of_copy": n * 76 / t / copy_bw})
    return rows


def bench_numpy(strands, count, steps=3):
    model_points = np.zeros((strands * count, 3))
    model_points[:, 0] = np.tile(np.arange(count) * 0.005, strands)
    counts = np.full(strands, count)
    x = baseline.pad_strands(model_points, counts)
    rest = np.zeros(x.shape[:2])
    rest[:, 1:] = 0.005
    v, c = np.zeros_like(x), np.zeros_like(x)
    roots = x[:, 0].copy()

    def run():
        nonlocal x, v, c
        for _ in range(steps):
            x, v, c = baseline.step(x, v, c, rest, counts, roots, dt=DT, gravity=G)

    t = Timer("cpu")(run, repeats=3) / steps
    return {"strands": strands, "particles_per_strand": count, "seconds_per_step": t,
            "particle_steps_per_s": strands * count / t}


def bench_fused(device, timer, strands_times_count, copy_bw, ks=(1, 2, 4, 8, 16, 32)):
    """Fused substeps against one step per launch, for several strand lengths, and against the
    per-step floor: the copy bandwidth over the form's minimal bytes per particle."""
    cases = [("float32", "prior", 8), ("float32", "prior", 16), ("float32", "prior", 24), ("float32", "prior", 32),
             ("float32", "posterior", 32), ("float64", "prior", 32),
             # longer strands: the pipelined kernel (one lane per substep)
             ("float32", "prior", 64), ("float32", "prior", 128), ("float64", "prior", 64)]
    rows = []
    for precision, correction, count in cases:
        strands = strands_times_count // count
        model, state = uniform_groom(strands, count, device=device, precision=precision,
                                     with_corrections=correction == "prior")
        control = model.control()
        unfused = dw.DFTLSolver(model, correction=correction, gravity=G, fused=False)
        fused = dw.DFTLSolver(model, correction=correction, gravity=G, fused=True)
        per_step = timer(lambda: unfused.advance(state, control, DT, 8)) / 8
        n = strands * count
        # equality: one frame of 8 substeps both ways from the same start
        arrays = [a for a in (state.positions, state.velocities, state.corrections) if a is not None]
        start = [wp.clone(a) for a in arrays]
        unfused.advance(state, control, DT, 8)
        ref = [a.numpy().copy() for a in arrays]
        for dst, src in zip(arrays, start):
            wp.copy(dst, src)
        fused.advance(state, control, DT, 8)
        diff = max(float(np.abs(a.numpy().astype(np.float64) - r).max()) for a, r in zip(arrays, ref))
        for k in ks:
            t = timer(lambda: fused.advance(state, control, DT, k)) / k
            if not fused._pipelined_runs:
                kernel = "on chip"
            elif wp.get_device(device).is_cuda and k not in CUDA_LANES:
                kernel = "per step"  # the CUDA pipeline needs one lane per substep
            else:
                kernel = "pipelined"
            rows.append({"kernel": kernel, "precision": precision, "correction": correction, "strands": strands,
                         "particles_per_strand": count, "substeps_per_launch": k,
                         "particle_substeps_per_s": n / t, "per_step_particle_steps_per_s": n / per_step,
                         "speedup_vs_per_step": per_step / t,
                         "of_floor": n / t / (copy_bw / minimal_bytes(precision, correction)),
                         "max_abs_diff_vs_unfused": diff})
        del model, state, start
    return rows


def bench_scaling(device, timer, copy_bw):
    cuda = wp.get_device(device).is_cuda
    strand_counts = (1000, 16000, 128000, 1 << 20, 4 << 20) if cuda else (1000, 4000, 16000)
    lengths = (8, 32, 128, 256) if cuda else (8, 32, 128)
    limit = (1 << 30) if cuda else (4 << 20)
    rows = []
    for strands in strand_counts:
        for count in lengths:
            if strands * count > limit:
                continue
            rows += bench_step(device, timer, copy_bw, strands, count, precisions=("float32",),
                               layouts=("interleaved",) if cuda else ("strand-major",), corrections=("prior",),
                               swapped=False)
    return rows


def bench_memory(device):
    device = wp.get_device(device)
    out = {}
    for precision in ("float32", "float64"):
        for correction in ("prior", "posterior"):
            for layout in ("interleaved", "particle-major") if device.is_cuda else ("strand-major",):
                model, state = uniform_groom(1024, 32, device=device, precision=precision,
                                             with_corrections=correction == "prior", **STEP_LAYOUTS[layout])
                fields = [state.storage] if state.storage is not None else [state.positions, state.velocities,
                                                                            state.corrections]
                arrays = [model.rest_lengths] + fields
                per_particle = sum(a.capacity for a in arrays if a is not None) / model.num_points
                per_strand = sum(a.capacity for a in (model.strand_base, model.strand_stride, model.strand_count,
                                                       model.root_rest)) / model.num_strands + 2 * 3 * (4 if precision == "float32" else 8)
                key = f"{precision}/{correction}" + ("" if layout == "interleaved" or not device.is_cuda else " (plain)")
                out[key] = {"bytes_per_particle": per_particle, "bytes_per_strand": per_strand, "layout": layout}
    if device.is_cuda:
        # the largest grooms take the plain layout: the interleaved one needs 3 slots per particle, past
        # 2^31 elements per array sooner (uniform_groom falls back to it by itself)
        out["largest"] = [largest_groom(device, precision, out[f"{precision}/prior (plain)"])
                          for precision in ("float32", "float64")]
    return out


def largest_groom(device, precision, per, count=32):
    """Allocate and step the largest groom of ``count``-vertex strands that fits: bounded by the
    free memory and by Warp's 2^31 - 1 elements per array."""
    free = device.free_memory
    by_memory = int(0.97 * free / (per["bytes_per_particle"] * count + per["bytes_per_strand"]))
    by_index = (2**31 - 1) // count
    strands = min(by_memory, by_index)
    model, state = uniform_groom(strands, count, device=device, precision=precision, interleave=1)
    solver = dw.DFTLSolver(model, gravity=G, fused=False)
    solver.advance(state, model.control(), DT, 1)
    wp.synchronize_device(device)
    diag = solver.diagnostics(state)
    return {"precision": precision, "strands": strands, "particles_per_strand": count, "particles": strands * count,
            "free_bytes_before": free, "limited_by": "memory" if by_memory < by_index else "2^31 elements per array",
            "stepped": bool(np.isfinite(diag["energy"])), "max_stretch_after_step": diag["max_stretch"]}


def machine_line(device):
    d = wp.get_device(device)
    cpu = platform.processor() or platform.machine()
    try:
        with open("/proc/cpuinfo") as f:
            cpu = next(line.split(":", 1)[1].strip() for line in f if line.startswith("model name"))
    except (OSError, StopIteration):
        pass
    return f"{d.name} ({d.alias}); host CPU {cpu}, {os.cpu_count()} cores; Warp {wp.__version__}"


def fmt(x, unit=""):
    for div, prefix in ((1e12, "T"), (1e9, "G"), (1e6, "M"), (1e3, "k")):
        if abs(x) >= div:
            return f"{x / div:.2f} {prefix}{unit}"
    return f"{x:.3g} {unit}"


def to_markdown(res):
    lines = [f"### {res['machine']}", "", f"Date {res['date']}. Command: `{res['command']}`", ""]
    if "copy" in res:
        c = res["copy"]
        lines += [f"Copy bandwidth ({c['bytes'] >> 20} MiB float32, bytes read + written): `wp.copy` "
                  f"{fmt(c['memcpy_Bps'], 'B/s')}, copy kernel {fmt(c['kernel_Bps'], 'B/s')}; ceiling used: "
                  f"**{fmt(c['bandwidth_Bps'], 'B/s')}**", ""]
    if "step" in res:
        lines += ["One step per launch, " + f"{res['step'][0]['strands']} strands x {res['step'][0]['particles_per_strand']} particles:", "",
                  "| precision | layout | correction | particle-steps/s | minimal B/particle | bandwidth | of copy | "
                  "of copy, swapped states |",
                  "|---|---|---|---|---|---|---|---|"]
        lines += [f"| {r['precision']} | {r['layout']} | {r['correction']} | {fmt(r['particle_steps_per_s'])} | "
                  f"{r['bytes_per_particle']} | {fmt(r['bandwidth_Bps'], 'B/s')} | {100 * r['of_copy']:.1f}% | "
                  + (f"{100 * r['of_copy_swapped']:.1f}% |" if "of_copy_swapped" in r else "— |")
                  for r in res["step"]]
        lines += ["", "*of copy*: `advance`, in place (one State, the memory-lean default); *swapped states*: "
                  "`step(state_in, state_out)` with two States swapped between steps (Newton style, twice the state memory)."]
        lines.append("")
    if "blocks" in res:
        lines += ["float32 prior step by thread-block size:", "", "| block_dim | particle-steps/s | of copy |", "|---|---|---|"]
        lines += [f"| {r['block_dim']} | {fmt(r['particle_steps_per_s'])} | {100 * r['of_copy']:.1f}% |" for r in res["blocks"]]
        lines.append("")
    if "numpy" in res:
        r = res["numpy"]
        lines += [f"numpy baseline (vectorized over strands, float64, prior), {r['strands']} x {r['particles_per_strand']}: "
                  f"**{fmt(r['particle_steps_per_s'])} particle-steps/s**", ""]
    if "fused" in res:
        lines += ["Fused substeps (state on chip), against one step per launch in the same run "
                  f"({res['fused'][0]['strands'] * res['fused'][0]['particles_per_strand'] / 1e6:.0f} M particles); "
                  "the last column is the largest difference of any state value after one 8-substep frame:", "",
                  "| kernel | precision | correction | particles/strand | k | particle-substeps/s | x per-step (measured) | "
                  "x per-step floor (copy) | max diff vs unfused |",
                  "|---|---|---|---|---|---|---|---|---|"]
        lines += [f"| {r.get('kernel', 'on chip')} | {r['precision']} | {r['correction']} | {r['particles_per_strand']} | "
                  f"{r['substeps_per_launch']} | "
                  f"{fmt(r['particle_substeps_per_s'])} | {r['speedup_vs_per_step']:.2f} | {r['of_floor']:.2f} | "
                  f"{r['max_abs_diff_vs_unfused']:.2g} |"
                  for r in res["fused"]]
        lines += ["", "*x per-step (measured)*: against the per-step kernel at the same strand length in this run; "
                  "*x per-step floor (copy)*: against the copy bandwidth over the form's minimal bytes per particle "
                  "(the fastest any one-step-per-launch kernel could go)."]
        lines.append("")
    if "scaling" in res:
        lines += ["Scaling (float32, prior, a frame of 10 substeps per graph launch; layout: the default, "
                  "interleaved unless its slots would pass 2^31):", "",
                  "| strands | particles/strand | layout | time/step | particle-steps/s | of copy |", "|---|---|---|---|---|---|"]
        lines += [f"| {r['strands']} | {r['particles_per_strand']} | "
                  f"{'interleaved' if r.get('interleave', 1) > 1 else r['layout'].replace('interleaved', 'particle-major')} | "
                  f"{r['seconds_per_step'] * 1e6:.1f} us | "
                  f"{fmt(r['particle_steps_per_s'])} | {100 * r['of_copy']:.1f}% |" for r in res["scaling"]]
        lines.append("")
    if "memory" in res:
        lines += ["Device memory (state + model arrays, measured from the allocations):", "",
                  "| precision/correction | B/particle | B/strand |", "|---|---|---|"]
        lines += [f"| {k} | {v['bytes_per_particle']:.0f} | {v['bytes_per_strand']:.0f} |"
                  for k, v in res["memory"].items() if k != "largest"]
        if any(k.endswith("(plain)") for k in res["memory"]):
            lines += ["", "Without *(plain)*: the CUDA default layout, state vectors interleaved per 32-strand "
                      "chunk (one buffer of 3 vectors per slot, 2 in the posterior form, which carries no "
                      "corrections; every per-particle model array spans the same slots: the rest lengths' unused "
                      "slots cost 2 x 4 B per particle in float32, 1 x 4 B in the posterior form). *(plain)*: "
                      "`Model.from_strands(..., interleave=1)`, the layout of the largest grooms below."]
        for big in res["memory"].get("largest", []):
            lines += ["", f"Largest groom allocated and stepped ({big['precision']}, prior): **{big['strands']:,} strands x "
                      f"{big['particles_per_strand']} = {big['particles'] / 1e9:.2f} G particles**, limited by "
                      f"{big['limited_by']} ({big['free_bytes_before'] / 2**30:.0f} GiB free before; stepped: "
                      f"{big['stepped']}, max stretch after the step {big['max_stretch_after_step']:.1e})"]
        lines.append("")
    return "\n".join(lines)


def plot(res, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 4.5))
    for count in sorted({r["particles_per_strand"] for r in res["scaling"]}):
        rows = [r for r in res["scaling"] if r["particles_per_strand"] == count]
        ax.plot([r["strands"] * count for r in rows], [r["particle_steps_per_s"] for r in rows], "o-",
                label=f"{count} particles/strand")
    if "copy" in res:
        ceiling = res["copy"]["bandwidth_Bps"] / minimal_bytes("float32", "prior")
        ax.axhline(ceiling, color="k", ls="--", label="copy-bandwidth ceiling (76 B/particle)")
    ax.set(xscale="log", yscale="log", xlabel="particles", ylabel="particle-steps / s",
           title=f"DFTL step (float32, prior) on {res['device_name']}")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--device", default="cpu")
    ap.add_argument("--sections", default="copy,step,blocks,numpy,fused,scaling,memory")
    ap.add_argument("--out", default=None, help="folder for results.json, bench-<device>.md, throughput.png")
    args = ap.parse_args(argv)
    wp.config.log_level = wp.LOG_WARNING
    wp.init()
    device = wp.get_device(args.device)
    sections = set(args.sections.split(","))
    timer = Timer(device)
    res = {"device": str(device), "device_name": device.name, "machine": machine_line(device),
           "date": datetime.date.today().isoformat(), "warp": wp.__version__,
           "command": "python scripts/bench.py " + " ".join(argv if argv is not None else sys.argv[1:])}
    copy_bw = None
    with wp.ScopedDevice(device):
        if sections & {"copy", "step", "scaling", "blocks", "fused"}:
            res["copy"] = bench_copy(device, timer)
            copy_bw = res["copy"]["bandwidth_Bps"]
            print(f"copy: {fmt(copy_bw, 'B/s')}", flush=True)
        strands, count = step_problem(device)
        if "step" in sections:
            res["step"] = bench_step(device, timer, copy_bw, strands, count,
                                     layouts=tuple(STEP_LAYOUTS) if wp.get_device(device).is_cuda else ("strand-major", "particle-major"))
            for r in res["step"]:
                print(f"step {r['precision']} {r['layout']} {r['correction']}: {fmt(r['particle_steps_per_s'])} "
                      f"particle-steps/s, {100 * r['of_copy']:.1f}% of copy", flush=True)
        if "blocks" in sections:
            res["blocks"] = bench_block_dim(device, timer, copy_bw, strands, count)
            for r in res["blocks"]:
                print(f"block_dim {r['block_dim']}: {fmt(r['particle_steps_per_s'])} ({100 * r['of_copy']:.1f}% of copy)", flush=True)
        if "numpy" in sections:
            res["numpy"] = bench_numpy(*((20000, 32) if device.is_cuda else (strands, count)))
            print(f"numpy: {fmt(res['numpy']['particle_steps_per_s'])} particle-steps/s", flush=True)
        if "fused" in sections:
            res["fused"] = bench_fused(device, timer, strands * count, copy_bw)
            for r in res["fused"]:
                print(f"fused {r['precision']} {r['correction']} n={r['particles_per_strand']} "
                      f"k={r['substeps_per_launch']}: x{r['speedup_vs_per_step']:.2f} per-step, "
                      f"x{r['of_floor']:.2f} floor "
                      f"(diff {r['max_abs_diff_vs_unfused']:.1g})", flush=True)
        if "scaling" in sections:
            res["scaling"] = bench_scaling(device, timer, copy_bw)
            print("scaling: done", flush=True)
        if "memory" in sections:
            res["memory"] = bench_memory(device)
            print(f"memory: {json.dumps(res['memory'])}", flush=True)
    md = to_markdown(res)
    print()
    print(md)
    if args.out:
        out = Path(args.out)
        out.mkdir(parents=True, exist_ok=True)
        tag = str(device).replace(":", "")
        (out / f"results-{tag}.json").write_text(json.dumps(res, indent=1))
        (out / f"bench-{tag}.md").write_text(md + "\n")
        if "scaling" in res:
            plot(res, out / f"throughput-{tag}.png")


if __name__ == "__main__":
    main()
