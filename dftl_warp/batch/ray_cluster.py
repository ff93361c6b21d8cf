"""``dftl-warp batch --ray ADDRESS``: the jobs of a batch as Ray tasks (``pip install 'dftl-warp[ray]'``).

``ADDRESS`` is a cluster address (``ray://host:10001``, ``host:6379``), ``auto`` (the cluster this
machine belongs to, as ``ray start`` left it) or ``local`` (start a Ray instance on this machine
for the batch). Every node needs dftl-warp installed and the jobs' inputs and outputs at the same
paths (a shared file system): checkpoints and resuming work as locally
(:mod:`dftl_warp.batch.checkpoint`), whichever node a job lands on.

A job on CUDA asks Ray for one GPU per device it names (``num_gpus``); Ray makes the GPUs it grants
the task's ``cuda:0``, ``cuda:1`` ... . Jobs without a ``device`` run on CUDA when the cluster has
GPUs, else on the CPU (one CPU each).
"""

from __future__ import annotations

import logging

from ..errors import UserError
from .jobs import Job
from .checkpoint import CheckpointPolicy, JobResult


def require_ray():
    """The ``ray`` module, or a one-line UserError saying how to install it."""
    try:
        import ray
    except ImportError:
        raise UserError("--ray: Ray is not installed; install it with: pip install 'dftl-warp[ray]'") from None
    return ray


def task_device(device: str) -> tuple[str, int]:
    """(device inside the Ray task, GPUs to request): the k-th CUDA device named becomes cuda:k."""
    from ..core.devices import parse_devices

    parts, gpus = [], 0
    for d in parse_devices(device):
        if d.startswith("cuda"):
            parts.append(f"cuda:{gpus}")
            gpus += 1
        else:
            parts.append(d)
    return ",".join(parts), gpus


def _ray_task(job: dict, device: str, policy: dict) -> dict:
    """Body of a Ray task: one job on ``device``; returns its JobResult as a dict."""
    from .checkpoint import run_job
    from ..core.devices import init_warp

    init_warp()
    return run_job(Job.from_dict(job), device, CheckpointPolicy(**policy)).as_dict()


def _check_reachable(address: str, timeout: float = 5.0) -> None:
    """Fail fast (Ray itself retries for minutes) when ``host:port`` does not answer."""
    import socket

    target = address.split("://", 1)[-1]
    host, _, port = target.rpartition(":")
    if not host or not port.isdigit():
        raise UserError(f"--ray {address}: expected 'auto', 'local', HOST:PORT or ray://HOST:PORT")
    try:
        socket.create_connection((host.strip("[]"), int(port)), timeout=timeout).close()
    except OSError as exc:
        raise UserError(f"--ray {address}: cannot connect: {exc.strerror or exc}") from None


def connect(address: str):
    ray = require_ray()
    if address not in ("auto", "local"):
        _check_reachable(address)
    options = {"logging_level": logging.ERROR, "log_to_driver": False}
    try:
        if address == "local":
            ray.init(include_dashboard=False, **options)
        else:
            ray.init(address=address, **options)
    except (ConnectionError, RuntimeError, ValueError) as exc:
        raise UserError(f"--ray {address}: cannot connect: {' '.join(str(exc).split())}") from None
    return ray


def run_ray(jobs: list[Job], address: str, *, policy: CheckpointPolicy | None = None,
            reporter=None) -> list[JobResult]:
    """Run ``jobs`` as Ray tasks on the cluster at ``address``; one result per job, in order."""
    from dataclasses import asdict

    from .scheduler import NullReporter

    policy = policy or CheckpointPolicy()
    reporter = reporter or NullReporter()
    results: dict[int, JobResult] = {}
    runnable = [job for job in jobs if job.error is None]
    ray = connect(address) if runnable else None
    for job in jobs:
        if job.error is not None:
            results[job.index] = JobResult(index=job.index, name=job.name, output=job.output, status="failed",
                                           device=job.device, error=job.error)
            reporter.result(job, results[job.index])
    if runnable:
        try:
            has_gpus = ray.cluster_resources().get("GPU", 0) > 0
            remote = ray.remote(_ray_task)
            refs = {}
            for job in runnable:
                device = job.device or ("cuda" if has_gpus else "cpu")
                inside, gpus = task_device(device)
                ref = remote.options(num_cpus=1, num_gpus=gpus, max_retries=1).remote(
                    job.as_dict(), inside, asdict(policy))
                refs[ref] = (job, device)
                reporter.queued(job, device)
            waiting = list(refs)
            while waiting:
                ready, waiting = ray.wait(waiting, num_returns=1)
                job, device = refs[ready[0]]
                try:
                    result = JobResult(**ray.get(ready[0]))
                    result.device = device
                except Exception as exc:  # noqa: BLE001 - a crashed task fails its job only
                    text = " ".join(str(exc).split())[:300]
                    result = JobResult(index=job.index, name=job.name, output=job.output, status="failed",
                                       device=device, error=f"{job.output}: Ray task failed: {type(exc).__name__}: {text}")
                results[job.index] = result
                reporter.result(job, result)
        finally:
            ray.shutdown()
    return [results[job.index] for job in jobs]
