"""``dftl-warp study``: measure the speed-accuracy trade (docs/accuracy.md)."""

from __future__ import annotations

import datetime
import os
import platform
import shlex
import sys

from ..errors import UserError


def add_parser(sub):
    p = sub.add_parser(
        "study", help="measure accuracy against cost: convergence, energy, stretch, modes, stability",
        description="Run the accuracy study (dftl_warp/study.py): sweeps of step, damping s, correction "
                    "form, precision and solver (dftl, ftl, pbd, reference) on standard scenarios; writes "
                    "CSV, PNG plots and accuracy.md into --out.")
    p.add_argument("--fast", action="store_true", help="the small subset that CI runs (seconds)")
    p.add_argument("--device", default=None,
                   help="Warp device, e.g. cpu or cuda:0 (default cuda:0 when there is a CUDA device, else cpu)")
    p.add_argument("--out", default="study", help="folder for CSV, PNG and accuracy.md (default ./study)")
    p.add_argument("--docs", default=None, help="also write the report here, image links relative to it")
    p.add_argument("--quiet", action="store_true", help="no progress lines")
    p.set_defaults(run=run)


def _cpu_name() -> str:
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def _command_line() -> str:
    """How this study was started, as the user typed it."""
    words = [shlex.quote(a) for a in sys.argv[1:]]
    if os.path.basename(sys.argv[0]) == "study.py":
        return " ".join(["python scripts/study.py", *words])
    return " ".join(["dftl-warp", *words])


def run(args) -> int:
    import warp as wp

    from ..study.sweeps import StudyConfig, run_study
    from ..study.report import write_results

    from ..core.devices import device_line, resolve_device

    args.device = resolve_device(args.device)
    try:
        device = wp.get_device(args.device)
    except (RuntimeError, ValueError, KeyError) as exc:
        raise UserError(f"--device {args.device}: not available ({exc})") from None

    if os.path.exists(args.out) and not os.path.isdir(args.out):
        raise UserError(f"--out {args.out}: exists and is not a folder")
    if not args.quiet:
        print(device_line(str(device)), file=sys.stderr)
    cfg = StudyConfig.fast(str(device)) if args.fast else StudyConfig(device=str(device))
    log = (lambda *a, **k: None) if args.quiet else (lambda msg: print(msg, flush=True))
    with wp.ScopedDevice(device):
        results = run_study(cfg, log)
    meta = {
        "command": _command_line(),
        "machine": platform.node() or "unknown host",
        "cpu": _cpu_name(),
        "cores": os.cpu_count(),
        "device": str(device),
        "device_name": device.name,
        "date": datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC"),
        "seconds": results["seconds"],
        "fast": args.fast,
        "chain_reference_substeps": cfg.chain_reference_substeps,
        "groom_reference_substeps": cfg.groom_reference_substeps,
        "groom_strands": cfg.groom_strands,
        "groom_particles": cfg.groom_particles,
        "energy_seconds": cfg.energy_seconds,
        "mode_masses": cfg.mode_masses,
        "mode_length": cfg.mode_masses * cfg.mode_segment,
        "mode_periods": cfg.mode_periods,
        "map_seconds": cfg.map_seconds,
    }
    written = write_results(results, meta, args.out, args.docs)
    log(f"study: {results['seconds']:.0f} s; wrote {len(written)} files to {args.out}"
        + (f" and {args.docs}" if args.docs else ""))
    return 0
