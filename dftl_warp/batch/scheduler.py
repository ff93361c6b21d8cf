"""``dftl-warp batch``: run the jobs of a JOBS.toml (:mod:`dftl_warp.batch.jobs`) in parallel.

Locally, jobs run in worker processes started with the ``spawn`` method (Warp and CUDA do not
survive ``fork``): one worker per CUDA device by default, each job on the least busy device unless
it names one; on a machine without CUDA, one worker per core on the CPU. Every job is resumable
(:mod:`dftl_warp.batch.checkpoint`): kill the batch at any moment, run it again, and completed jobs are
skipped while the others continue from their last checkpoint. Workers die with the batch process
(``PR_SET_PDEATHSIG`` on Linux, a parent watchdog elsewhere); a worker that crashes fails only the
job it was running. :mod:`dftl_warp.batch.ray_cluster` runs the same jobs on a Ray cluster.
"""

from __future__ import annotations

import contextlib
import os
import queue
import signal
import sys
import threading
import time
from collections import Counter, deque
from dataclasses import asdict

from ..core.devices import parse_devices
from .jobs import Job
from .checkpoint import CheckpointPolicy, JobResult, clean_interrupted


# -- devices --------------------------------------------------------------------------------------


def local_devices() -> list[str]:
    """CUDA devices of this machine (``cuda:N``), or ``["cpu"]`` when there are none."""
    import warp as wp

    from ..core.devices import init_warp

    init_warp()
    count = wp.get_cuda_device_count()
    return [f"cuda:{i}" for i in range(count)] if count else ["cpu"]


def default_workers(num_jobs: int, devices: list[str]) -> int:
    """One worker per CUDA device; on the CPU one per core; never more than there are jobs."""
    per_machine = len(devices) if devices != ["cpu"] else (os.cpu_count() or 1)
    return max(1, min(per_machine, num_jobs))


class DevicePicker:
    """Gives each job its device: the one it names, else the least busy local device."""

    def __init__(self, devices: list[str]):
        self.devices = list(devices)
        self.busy: Counter = Counter()

    def take(self, job: Job) -> str:
        device = job.device or min(self.devices, key=lambda d: (self.busy[d], self.devices.index(d)))
        for d in parse_devices(device):
            self.busy[d] += 1
        return device

    def release(self, device: str) -> None:
        for d in parse_devices(device):
            self.busy[d] -= 1


# -- worker processes -------------------------------------------------------------------------------


def _die_with_parent(parent_pid: int) -> None:
    """Make this worker end when the batch process ends, however it ends (SIGKILL included)."""
    if sys.platform.startswith("linux"):
        try:
            import ctypes

            libc = ctypes.CDLL(None, use_errno=True)
            libc.prctl(1, signal.SIGKILL)  # PR_SET_PDEATHSIG
        except (OSError, AttributeError):
            pass
    if os.getppid() != parent_pid:  # the parent died before the line above
        os._exit(1)

    def watch():
        while True:
            time.sleep(0.5)
            if os.getppid() != parent_pid:
                os._exit(1)

    threading.Thread(target=watch, daemon=True, name="parent-watchdog").start()


def _worker_main(inbox, outbox, parent_pid: int) -> None:
    """A worker process: run the jobs it is sent until it gets None."""
    _die_with_parent(parent_pid)
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the batch process handles Ctrl-C
    from .checkpoint import run_job
    from ..core.devices import init_warp

    init_warp()
    while True:
        task = inbox.get()
        if task is None:
            return
        job = Job.from_dict(task["job"])
        last = [0.0]

        def progress(event, job=job, last=last):
            now = time.monotonic()
            if event["event"] == "frames" and now - last[0] < 0.1:
                return  # at most ten progress messages per second
            last[0] = now
            outbox.put(("event", job.index, event))

        result = run_job(job, task["device"], CheckpointPolicy(**task["policy"]), progress)
        outbox.put(("result", job.index, result.as_dict()))


class _Worker:
    def __init__(self, ctx, outbox):
        self.inbox = ctx.Queue()
        self.process = ctx.Process(target=_worker_main, args=(self.inbox, outbox, os.getpid()), daemon=True)
        # Ctrl-C is the batch's, not even the worker's while it imports (it inherits the mask); a
        # signal to the batch waits until the worker has its start-up data (else: its EOFError)
        try:
            with _signals_deferred(), _blocked("SIGINT"):
                self.process.start()
        except BaseException:  # a signal that came meanwhile: this worker goes too
            if self.process.is_alive():
                self.process.kill()
            raise
        #: (job, device) being run, or None
        self.task = None

    def send(self, job: Job, device: str, policy: CheckpointPolicy) -> None:
        self.task = (job, device)
        self.inbox.put({"job": job.as_dict(), "device": device, "policy": asdict(policy)})

    def stop(self) -> None:
        if self.process.is_alive():
            self.inbox.put(None)


def run_local(jobs: list[Job], *, workers: int | None = None, policy: CheckpointPolicy | None = None,
              reporter=None, devices: list[str] | None = None) -> list[JobResult]:
    """Run ``jobs`` in worker processes on this machine; returns one result per job, in order."""
    import multiprocessing as mp

    policy = policy or CheckpointPolicy()
    reporter = reporter or NullReporter()
    results: dict[int, JobResult] = {}
    for job in jobs:
        if job.error is not None:
            results[job.index] = JobResult(index=job.index, name=job.name, output=job.output,
                                           status="failed", device=job.device, error=job.error)
            reporter.result(job, results[job.index])
    pending = deque(job for job in jobs if job.error is None)
    if pending:
        devices = devices or local_devices()
        picker = DevicePicker(devices)
        count = workers or default_workers(len(pending), devices)
        ctx = mp.get_context("spawn")
        start_resource_tracker()
        outbox = ctx.Queue()
        pool = []
        by_index = {job.index: job for job in jobs}
        try:
            for _ in range(min(count, len(pending))):   # one by one: a signal meanwhile stops those started
                pool.append(_Worker(ctx, outbox))
            _dispatch(pool, pending, picker, policy, outbox, by_index, results, reporter, ctx)
        except BaseException:  # Ctrl-C, SIGTERM, SIGHUP: stop the workers now; their checkpoints stay
            for w in pool:
                if w.process.is_alive():
                    w.process.kill()
            raise
        finally:
            for w in pool:
                w.stop()
            deadline = time.monotonic() + 5.0
            for w in pool:
                w.process.join(max(0.0, deadline - time.monotonic()))
                if w.process.is_alive():
                    w.process.kill()
                    w.process.join()
            for w in pool:  # interrupted jobs: partial and lock files go, checkpoints stay (resume)
                if w.task is not None:
                    clean_interrupted(w.task[0].output)
    return [results[job.index] for job in jobs]


def start_resource_tracker() -> None:
    """Start multiprocessing's resource tracker (the queues' semaphores register with it) with
    SIGHUP blocked. It ignores SIGINT and SIGTERM itself but not SIGHUP, so a SIGHUP to the
    batch's process group (a closed terminal or SSH session, a farm's kill) killed it and the
    batch's last lines were its KeyError tracebacks. The batch process keeps its own SIGHUP
    handling (a SIGHUP that comes meanwhile is delivered once the mask is restored)."""
    from multiprocessing import resource_tracker

    with _blocked("SIGHUP"):
        resource_tracker.ensure_running()


@contextlib.contextmanager
def _signals_deferred():
    """SIGINT, SIGTERM and SIGHUP that come meanwhile are handled (by the handlers in place, such
    as the CLI's) once the block is left. Only in the main thread (elsewhere it does nothing)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    came, previous = [], {}
    for name in ("SIGINT", "SIGTERM", "SIGHUP"):
        if hasattr(signal, name):
            signum = getattr(signal, name)
            previous[signum] = signal.signal(signum, lambda number, frame: came.append(number))
    try:
        yield
    finally:
        for signum, handler in previous.items():
            signal.signal(signum, handler)
        if came:
            signal.raise_signal(came[0])


@contextlib.contextmanager
def _blocked(*names):
    """The signals ``names`` blocked in this thread meanwhile: a process started meanwhile inherits
    the mask (a signal sent to it stays pending); this one gets any that came once they are
    unblocked."""
    signums = {getattr(signal, n) for n in names if hasattr(signal, n)}
    if not signums or not hasattr(signal, "pthread_sigmask"):  # pragma: no cover - not POSIX
        yield
        return
    previous = signal.pthread_sigmask(signal.SIG_BLOCK, signums)
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, previous)


def _dispatch(pool, pending, picker, policy, outbox, by_index, results, reporter, ctx) -> None:
    def finish(worker, result: JobResult) -> None:
        job, device = worker.task
        worker.task = None
        picker.release(device)
        results[job.index] = result
        reporter.result(job, result)

    while pending or any(w.task for w in pool):
        for w in pool:
            if w.task is None and pending:
                job = pending.popleft()
                device = picker.take(job)
                w.send(job, device, policy)
                reporter.queued(job, device)
        try:
            kind, index, payload = outbox.get(timeout=0.25)
        except queue.Empty:
            for k, w in enumerate(pool):
                if w.task is not None and not w.process.is_alive():
                    job, device = w.task
                    code = w.process.exitcode
                    why = f"killed by signal {-code}" if code is not None and code < 0 else f"exit status {code}"
                    finish(w, JobResult(index=job.index, name=job.name, output=job.output, status="failed",
                                        device=device, error=f"{job.output}: worker process died ({why})"))
                    clean_interrupted(job.output)  # its checkpoint stays: a rerun resumes from it
                    pool[k] = _Worker(ctx, outbox)
            continue
        worker = next((w for w in pool if w.task is not None and w.task[0].index == index), None)
        if worker is None:
            continue
        if kind == "event":
            reporter.event(by_index[index], payload)
        elif kind == "result":
            finish(worker, JobResult(**payload))


# -- reporting --------------------------------------------------------------------------------------


class NullReporter:
    """Reports nothing."""

    def queued(self, job, device):
        pass

    def event(self, job, event):
        pass

    def result(self, job, result):
        pass

    def close(self):
        pass


class Reporter(NullReporter):
    """Progress on stderr: a live bar per job on a terminal (rich), else a line per job event."""

    def __init__(self, num_jobs: int, *, quiet: bool = False, console=None):
        from rich.console import Console

        self.console = console or Console(stderr=True)
        self.quiet = quiet
        self.num_jobs = num_jobs
        self.progress = None
        self.tasks: dict[int, int] = {}
        self.devices: dict[int, str] = {}
        #: per-job line progress when stderr is not a terminal (dftl_warp.output.progress)
        self.lines: dict = {}
        #: job index -> the warnings printed (or, with --quiet, held for the summary)
        self.warned: dict[int, list[str]] = {}
        if not quiet and self.console.is_terminal:
            from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

            self.progress = Progress(
                TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(), TextColumn("frames"),
                TimeElapsedColumn(), TextColumn("{task.fields[status]}"),
                console=self.console, transient=False,
            )
            self.progress.start()

    def _label(self, job) -> str:
        return f"[{job.index}/{self.num_jobs}] {job.name}"

    def _line(self, text: str) -> None:
        if self.quiet:
            return
        if self.progress is not None:
            self.progress.console.print(text, markup=False, highlight=False)
        else:
            print(f"dftl-warp: {text}", file=sys.stderr, flush=True)

    def queued(self, job, device):
        self.devices[job.index] = device

    def event(self, job, event):
        kind = event["event"]
        if kind == "start":
            resumed = event.get("resumed_from")
            text = f"{self._label(job)}: frames {event['first']}..{event['last']} on {self.devices.get(job.index)}"
            if resumed is not None:
                text += f", resuming after frame {resumed}"
            if self.progress is not None:
                done = 0 if resumed is None else resumed - event["first"] + 1
                self.tasks[job.index] = self.progress.add_task(
                    self._label(job), total=event["total"], completed=done, status=str(self.devices.get(job.index)))
            else:
                self._line(text)
                if not self.quiet:  # not a terminal: a line per 10 % of the job or per minute
                    from ..output.progress import LineProgress

                    line = self.lines[job.index] = LineProgress(event["total"], self._label(job), "frames",
                                                                sys.stderr)
                    line.n = line._last_n = 0 if resumed is None else resumed - event["first"] + 1
        elif kind == "frames" and self.progress is not None and job.index in self.tasks:
            self.progress.update(self.tasks[job.index], completed=event["done"])
        elif kind == "frames" and job.index in self.lines:
            self.lines[job.index].set(event["done"])
        elif kind == "note":
            self._line(f"{self._label(job)}: {event['text']}")
        elif kind == "warning":
            self._warning(job, event["text"])

    def _warning(self, job, text: str) -> None:
        """``dftl-warp: warning: job N (NAME): ...`` on stderr, once per warning (with --quiet:
        left to the summary, :func:`warning_lines`)."""
        self.warned.setdefault(job.index, []).append(text)
        if self.quiet:
            return
        line = f"dftl-warp: warning: {job_label(job.index, job.name)}: {text}"
        if self.progress is not None:
            self.progress.console.print(line, markup=False, highlight=False)
        else:
            print(line, file=sys.stderr, flush=True)

    def result(self, job, result):
        shown = list(self.warned.get(job.index, []))
        for text in result.warnings:  # those no event brought (Ray, a worker's last moments)
            if text in shown:
                shown.remove(text)
            else:
                self._warning(job, text)
        if self.progress is not None and job.index in self.tasks:
            self.progress.update(self.tasks[job.index], completed=result.total_frames if result.ok else None,
                                 status=result.status)
        self._line(f"{self._label(job)}: {describe(result)}")

    def close(self):
        if self.progress is not None:
            self.progress.stop()
            self.progress = None


def job_label(index: int, name: str) -> str:
    """``job 3 (sh020)``: how the error and warning lines name a job."""
    return f"job {index} ({name})"


def warning_lines(results: list[JobResult]) -> list[str]:
    """``dftl-warp: warning: job N (NAME): ...`` for every warning of every job, in job order."""
    return [f"dftl-warp: warning: {job_label(r.index, r.name)}: {w}" for r in results for w in r.warnings]


def describe(result: JobResult) -> str:
    if result.status == "skipped":
        return "skipped: already complete"
    if result.status == "failed":
        return f"failed: {result.error}"
    text = f"done: {result.frames} frames in {result.seconds:.2f} s ({result.frames_per_second:.1f} frames/s)"
    if result.resumed_from is not None:
        text += f", resumed after frame {result.resumed_from}"
    if result.warnings:
        text += f", {len(result.warnings)} warning{'s' if len(result.warnings) > 1 else ''}"
    return text


def summary_table(results: list[JobResult]):
    """A rich Table of the results: one row per job."""
    from rich.table import Table

    table = Table(title="dftl-warp batch", title_justify="left")
    for name, justify in (("#", "right"), ("job", "left"), ("device", "left"), ("frames", "right"),
                          ("resumed", "right"), ("wall s", "right"), ("frames/s", "right"), ("status", "left"),
                          ("warnings", "right")):
        table.add_column(name, justify=justify)
    for r in results:
        table.add_row(
            str(r.index), r.name, r.device or "-", f"{r.frames}/{r.total_frames}",
            "-" if r.resumed_from is None else str(r.resumed_from), f"{r.seconds:.2f}",
            f"{r.frames_per_second:.1f}" if r.frames else "-", r.status, str(len(r.warnings)) if r.warnings else "-",
        )
    return table


def totals(results: list[JobResult], seconds: float) -> str:
    """One line: how many jobs did what, and the batch's throughput."""
    counts = Counter(r.status for r in results)
    frames = sum(r.frames for r in results)
    rate = (lambda n: n / seconds) if seconds > 0 else (lambda n: 0.0)
    return (
        f"{len(results)} jobs: {counts['done']} done, {counts['skipped']} skipped, {counts['failed']} failed "
        f"in {seconds:.2f} s ({rate(len(results)):.2f} jobs/s, {rate(frames):.1f} frames/s)"
    )
