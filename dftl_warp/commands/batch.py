"""``dftl-warp batch JOBS.toml``: simulate many stages, in parallel, resumably (docs/batch.md)."""

from __future__ import annotations

import sys


def add_parser(sub):
    from ..output.paths import path_argument

    p = sub.add_parser(
        "batch",
        help="simulate the jobs of a JOBS.toml in parallel (resumable; locally or on Ray)",
        description=(
            "Run every [[job]] of JOBS.toml (input, output, and any simulate option by its long name) "
            "in parallel worker processes: one per GPU by default, else one per CPU core. Jobs "
            "checkpoint as they go: run the same command again after an interruption and completed "
            "jobs are skipped, the others resume. Exit status 0 when every job succeeded, 1 otherwise."
        ),
    )
    p.add_argument("jobs", metavar="JOBS.toml", type=path_argument("the job list, such as jobs.toml"),
                   help="job list (see docs/batch.md)")
    p.add_argument("--workers", type=_positive_int, metavar="N",
                   help="parallel jobs (default: one per CUDA device, else one per CPU core)")
    p.add_argument("--ray", metavar="ADDRESS",
                   help="run the jobs as Ray tasks: a cluster address, 'auto' (the running cluster) "
                        "or 'local' (start a Ray instance on this machine); needs dftl-warp[ray]")
    p.add_argument("--checkpoint-frames", type=_non_negative_int, default=0, metavar="N",
                   help="checkpoint every N frames (default 0: by time only)")
    p.add_argument("--checkpoint-seconds", type=_non_negative_float, default=30.0, metavar="S",
                   help="checkpoint every S seconds of wall time (default 30; 0: by frames only)")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress; only the summary table")
    p.set_defaults(run=run)


def _number(text, kind, low, what):
    import argparse
    import math

    try:
        value = kind(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
    if (isinstance(value, float) and math.isnan(value)) or value < low:
        raise argparse.ArgumentTypeError(f"must be {what}, got {text}")
    return value


def _positive_int(text):
    return _number(text, int, 1, ">= 1")


def _non_negative_int(text):
    return _number(text, int, 0, ">= 0")


def _non_negative_float(text):
    return _number(text, float, 0.0, ">= 0")


def run(args) -> int:
    import time

    from rich.console import Console

    from ..batch.scheduler import Reporter, job_label, run_local, summary_table, totals, warning_lines
    from ..errors import UserError
    from ..batch.jobs import load_jobs
    from ..batch.checkpoint import CheckpointPolicy

    if args.ray is not None:
        from ..batch.ray_cluster import require_ray

        require_ray()
    jobs = load_jobs(args.jobs)
    policy = CheckpointPolicy(every_frames=args.checkpoint_frames, every_seconds=args.checkpoint_seconds)
    if not policy.every_frames and not policy.every_seconds:
        raise UserError("--checkpoint-frames and --checkpoint-seconds are both 0: jobs would never checkpoint")
    reporter = Reporter(len(jobs), quiet=args.quiet)
    start = time.perf_counter()
    try:
        if args.ray is not None:
            from ..batch.ray_cluster import run_ray

            results = run_ray(jobs, args.ray, policy=policy, reporter=reporter)
        else:
            results = run_local(jobs, workers=args.workers, policy=policy, reporter=reporter)
    finally:
        reporter.close()
    seconds = time.perf_counter() - start
    out = Console(file=sys.stdout, width=None if sys.stdout.isatty() else 120)
    out.print(summary_table(results))
    print(totals(results, seconds), flush=True)
    if args.quiet:  # the warnings were held back for the summary
        for line in warning_lines(results):
            print(line, file=sys.stderr)
    for r in results:
        if not r.ok:
            print(f"dftl-warp: error: {job_label(r.index, r.name)}: {r.error}", file=sys.stderr)
    return 0 if all(r.ok for r in results) else 1
