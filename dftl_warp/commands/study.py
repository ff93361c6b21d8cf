"""``dftl-warp study``: measure the speed-accuracy trade (docs/accuracy.md)."""

from __future__ import annotations

import datetime
import os
import platform
import shlex
import sys

from ..errors import UserError


def add_parser(sub):
    from ..output.paths import path_argument

    p = sub.add_parser(
        "study", help="measure accuracy against cost: convergence, energy, stretch, modes, stability",
        description="Run the accuracy study (dftl_warp/study.py): sweeps of step, damping s, correction "
                    "form, precision and solver (dftl, ftl, pbd, reference) on standard scenarios; writes "
                    "CSV, PNG plots and accuracy.md into --out.")
    p.add_argument("--fast", action="store_true", help="the small subset that CI runs (seconds)")
    p.add_argument("--device", default=None,
                   help="Warp device, e.g. cpu or cuda:0 (default cuda:0 when there is a CUDA device, else cpu)")
    p.add_argument("--out", default="study", type=path_argument("the folder to write into"), help="folder for CSV, PNG and accuracy.md (default ./study)")
    p.add_argument("--docs", default=None, type=path_argument("the markdown file to write"), help="also write the report here, image links relative to it")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress lines")
    front = p.add_argument_group(
        "the front at scale (docs/accuracy-h200/front.md)",
        "--front runs only the GPU-scale section: every solver and setting on a released groom of "
        "--strands x --particles against the float64 reference; writes front.json, front.md and front.png "
        "into --out, with the quality presets re-derived from it. With --fast: a few settings (a CPU smoke run).")
    front.add_argument("--front", action="store_true", help="run the front at scale instead of the CPU sections")
    front.add_argument("--front-from", metavar="JSON", default=None, type=path_argument("a front.json to redraw"),
                       help="redraw front.md and front.png into --out from a front.json, without running (the run's "
                            "flags do nothing, --docs is refused; a file that is not a front.json writes nothing)")
    front.add_argument("--strands", type=int, default=None,
                       help="strands of the front's groom, 1 to 10,000,000 (default 100000; 64 with --fast)")
    front.add_argument("--particles", type=int, default=32, help="particles per strand, 2 to 1024 (default 32)")
    front.add_argument("--frames", type=int, default=None, help="frames at 24 fps, 1 to 10,000 (default 12; 3 with --fast)")
    front.add_argument("--reference-substeps", type=int, default=64,
                       help="substeps per frame of the float64 reference that is the truth, 2 to 16384 (default 64)")
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


def _command_line(args=None) -> str:
    """How this study was started, as the user typed it (``args.argv``: the words after the program)."""
    if os.path.basename(sys.argv[0]) == "study.py":
        return " ".join(["python scripts/study.py", *(shlex.quote(a) for a in sys.argv[1:])])
    words = [shlex.quote(a) for a in getattr(args, "argv", None) or sys.argv[1:]]
    return " ".join(["dftl-warp", *words])


#: the largest sane value of each --front flag: past it a typo that would fill any memory or run
#: for days (the front at scale is 100,000 strands x 32 particles, 12 frames, 64 substeps)
FRONT_LIMITS = {"--strands": 10_000_000, "--particles": 1024, "--frames": 10_000, "--reference-substeps": 16384}
#: the most particles of the front's groom (--strands x --particles): Warp indexes arrays with 32-bit integers
FRONT_MAX_PARTICLES = 2**31 - 1


def _check_front_args(args) -> None:
    if args.strands is None:
        args.strands = 64 if args.fast else 100_000
    if args.frames is None:
        args.frames = 3 if args.fast else 12
    for flag, value, low in (("--strands", args.strands, 1), ("--particles", args.particles, 2),
                             ("--frames", args.frames, 1), ("--reference-substeps", args.reference_substeps, 2)):
        if value < low:
            raise UserError(f"{flag} {value}: must be at least {low}")
        if value > FRONT_LIMITS[flag]:
            raise UserError(f"{flag} {value}: must be at most {FRONT_LIMITS[flag]:,}")
    if args.strands * args.particles > FRONT_MAX_PARTICLES:
        raise UserError(f"--strands {args.strands} x --particles {args.particles} = {args.strands * args.particles:,} "
                        f"particles: at most {FRONT_MAX_PARTICLES:,}")
    if args.docs:
        raise UserError("--docs: the front writes its report into --out (front.md); leave --docs out")


def args_default(flag: str):
    """The default of a --front flag (warned about when given without --front)."""
    return {"particles": 32, "reference_substeps": 64}.get(flag)


def _elapsed(args) -> str:
    """The run's wall time so far, as the final line prints it (``4.3 s``)."""
    import time

    return f"{time.perf_counter() - args.started:.1f} s"


def run_front(args, device, log) -> int:
    """``--front``: measure the front at scale and write it into ``--out``."""
    import warp as wp

    from ..study.front import SMOKE_SETTINGS, measure_front
    from ..study.front_report import write_front

    try:
        with wp.ScopedDevice(device):
            result = measure_front(strands=args.strands, particles=args.particles, frames=args.frames,
                                   reference_substeps=args.reference_substeps, device=str(device),
                                   settings=SMOKE_SETTINGS if args.fast else None, log=log)
    except MemoryError:
        raise UserError(f"--strands {args.strands} x --particles {args.particles}: the front's groom does not fit in "
                        f"the memory of this machine; give fewer") from None
    meta = {"command": _command_line(args), "machine": platform.node() or "unknown host", "cpu": _cpu_name(),
            "cores": os.cpu_count(), "device": str(device), "device_name": device.name, "warp": wp.config.version,
            "date": datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC"), "fast": args.fast}
    written = write_front(result, meta, args.out)
    log(f"study --front: {_elapsed(args)}; wrote {', '.join(written)}")
    return 0


def run_front_from(args, log) -> int:
    """``--front-from``: redraw the front's report into ``--out`` from a front.json, running nothing.
    A file that is not a front.json is one line and writes nothing; the flags that size or place a
    run (``--docs`` refused, as with ``--front``; the others warned about) do nothing here."""
    from ..study.front_report import load_front, write_front

    if args.docs:
        raise UserError("--docs: --front-from writes its report into --out (front.md); leave --docs out")
    given = (("--front", args.front), ("--fast", args.fast), ("--device", args.device is not None),
             ("--strands", args.strands is not None), ("--frames", args.frames is not None),
             ("--particles", args.particles != args_default("particles")),
             ("--reference-substeps", args.reference_substeps != args_default("reference_substeps")))
    idle = [flag for flag, on in given if on]
    if idle:
        print(f"dftl-warp: warning: {', '.join(idle)} {'does' if len(idle) == 1 else 'do'} nothing with --front-from "
              "(it redraws the report from the json, running nothing)", file=sys.stderr)
    try:
        result, meta = load_front(args.front_from)
    except (OSError, ValueError, KeyError, TypeError, AttributeError, IndexError) as exc:
        why = f"no {exc}" if isinstance(exc, KeyError) else str(exc)
        raise UserError(f"--front-from {args.front_from}: not a front.json ({why})") from None
    try:
        written = write_front(result, meta, args.out)
    except (ValueError, KeyError, TypeError, AttributeError, IndexError) as exc:   # made before writing
        why = f"no {exc}" if isinstance(exc, KeyError) else str(exc)
        raise UserError(f"--front-from {args.front_from}: not a front.json ({why})") from None
    except OSError as exc:
        raise UserError(f"--out {args.out}: cannot write: {exc.strerror or exc}") from None
    log(f"study --front-from: wrote {', '.join(written)}")
    return 0


def run(args) -> int:
    import time

    import warp as wp

    args.started = time.perf_counter()   # the elapsed time printed at the end: the whole run, Warp's start included
    from ..output.paths import check_folder
    from ..output.progress import stderr_line

    check_folder(args.out, f"--out {args.out}")   # before the study runs (minutes to hours), not after
    if args.docs and not args.front_from and not args.front:
        check_folder(os.path.dirname(args.docs) or ".", f"--docs {args.docs}")

    # progress, as every command's: on stderr, prefixed (stdout is left to results)
    log = (lambda *a, **k: None) if args.quiet else (lambda msg: print(stderr_line(msg), file=sys.stderr, flush=True))
    if args.front_from:
        return run_front_from(args, log)
    if args.front:
        _check_front_args(args)
    else:
        for flag in ("strands", "frames", "particles", "reference_substeps"):
            if getattr(args, flag) not in (None, args_default(flag)):
                print(f"dftl-warp: warning: --{flag.replace('_', '-')} does nothing without --front (it sizes the "
                      "front's groom)", file=sys.stderr)

    from ..core.devices import DeviceNotFound, device_line, lookup_device, resolve_device

    args.device = resolve_device(args.device)
    try:
        device = lookup_device(args.device)
    except DeviceNotFound as exc:
        raise UserError(f"--device {args.device}: {exc}") from None

    if not args.quiet:
        print(device_line(str(device)), file=sys.stderr)
    if args.front:
        return run_front(args, device, log)
    from ..study.report import write_results
    from ..study.sweeps import StudyConfig, run_study

    cfg = StudyConfig.fast(str(device)) if args.fast else StudyConfig(device=str(device))
    with wp.ScopedDevice(device):
        results = run_study(cfg, log)
    meta = {
        "command": _command_line(args),
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
    log(f"study: {_elapsed(args)}; wrote {len(written)} files to {args.out}"
        + (f" and {args.docs}" if args.docs else ""))
    return 0
