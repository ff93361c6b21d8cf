"""What a render-farm wrangler hits: outputs behind symlinks, folders that are files, runs killed
with SIGKILL (their leftovers), and the job file's one-line refusals."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from batch_stages import groom_stage, hidden_files, write_jobs
from dftl_warp.batch.checkpoint import run_job
from dftl_warp.batch.jobs import Job, load_jobs


@pytest.fixture(scope="module")
def stage(tmp_path_factory):
    return groom_stage(tmp_path_factory.mktemp("in") / "groom.usda", strands=8, vertices=6, end=8)


def test_two_jobs_writing_one_file_through_a_symlinked_folder_are_refused(tmp_path, stage):
    """``out/a.usdc`` and ``link/a.usdc`` with ``link -> out`` are one file: the second job is
    refused at load time (it would overwrite the first's output, and each rerun would redo both)."""
    (tmp_path / "out").mkdir()
    (tmp_path / "link").symlink_to("out")
    jobs = load_jobs(write_jobs(tmp_path / "jobs.toml", [
        {"input": str(stage), "output": "out/a.usdc"},
        {"input": str(stage), "output": "link/a.usdc"},
    ]))
    assert jobs[0].error is None
    assert jobs[1].error is not None and "link/a.usdc is also the output of job 1" in jobs[1].error


def test_an_output_folder_that_is_a_file_fails_the_job_in_one_line(tmp_path, stage):
    """``output = "afile/x.usdc"`` where ``afile`` is a file: the job fails with the one line
    simulate gives, not an internal error."""
    (tmp_path / "afile").write_text("")
    job = Job(index=1, name="x", input=str(stage), output=str(tmp_path / "afile" / "x.usdc"), options={"end": 2})
    result = run_job(job, "cpu")
    assert result.status == "failed"
    assert "internal error" not in result.error, result.error
    assert "cannot write" in result.error and "afile" in result.error, result.error


def test_simulate_removes_the_partial_files_of_runs_killed_before_it(tmp_path, stage):
    """A simulate killed with SIGKILL leaves its hidden partial file (nothing can remove it then);
    the next run of that output, holding its lock, removes such leftovers (its own, a batch job's
    partial file, USD's text export) and leaves the batch's checkpoint, which a rerun resumes from."""
    from dftl_warp.output.usd import UsdWriter
    from dftl_warp.simulation.simulate import simulate_usd
    from dftl_warp.usd.read import read_scene

    out = tmp_path / "o.usdc"
    killed = UsdWriter.create(out, read_scene(str(stage)), frames=(1, 2))   # a run that never ended
    killed.write_frame(1, [(c.points, c.points * 0) for c in read_scene(str(stage)).curves])
    killed.flush()
    assert killed.partial.stat().st_size > 0
    (tmp_path / ".o.usdc.dftl-partial.usdc").write_bytes(b"batch")            # a batch job's, killed
    (tmp_path / ".o.usdc.dftl-partial.k3j9x2ab.usda").write_bytes(b"text")   # a .usda export, killed
    (tmp_path / ".o.usdc.dftl-checkpoint.npz").write_bytes(b"kept")          # a batch's checkpoint
    simulate_usd(str(stage), str(out), end=2)
    assert out.is_file()
    assert hidden_files(tmp_path) == [".o.usdc.dftl-checkpoint.npz"]


def test_a_frame_step_that_leaves_out_the_last_frames_warns_once(tmp_path, stage, capsys):
    """``--frame-step 3`` over frames 1..8 writes 1, 4, 7: frame 8 is neither simulated nor
    written. simulate and a batch job say so in one warning each; a range the step divides says nothing."""
    from dftl_warp import cli

    out = tmp_path / "step.usdc"
    assert cli.main(["simulate", str(stage), "-o", str(out), "--end", "8", "--frame-step", "3", "--device", "cpu"]) == 0
    warnings = [line for line in capsys.readouterr().err.splitlines() if line.startswith("dftl-warp: warning:")]
    assert len(warnings) == 1 and "--frame-step 3" in warnings[0] and "ends at frame 7" in warnings[0], warnings
    assert "frame 8" in warnings[0]
    job = Job(index=1, name="s", input=str(stage), output=str(tmp_path / "job.usdc"),
              options={"end": 8, "frame_step": 3})
    result = run_job(job, "cpu")
    assert result.status == "done" and result.total_frames == 7
    assert len(result.warnings) == 1 and "frame_step 3" in result.warnings[0] and "frame 8" in result.warnings[0]
    divides = run_job(Job(index=2, name="d", input=str(stage), output=str(tmp_path / "d.usdc"),
                          options={"end": 7, "frame_step": 3}), "cpu")
    assert divides.status == "done" and divides.warnings == []


@pytest.mark.skipif(not Path("/proc").is_dir() or not hasattr(signal, "SIGHUP"), reason="needs /proc and SIGHUP")
def test_the_batchs_resource_tracker_survives_a_sighup_to_the_process_group():
    """multiprocessing's resource tracker ignores SIGINT and SIGTERM, not SIGHUP: a SIGHUP to the
    batch's process group (a closed SSH session) killed it, and the batch ended with its KeyError
    tracebacks after "stopped by SIGHUP". The batch starts it with SIGHUP blocked."""
    code = ("from multiprocessing import resource_tracker as r\n"
            "from dftl_warp.batch.scheduler import start_resource_tracker\n"
            "start_resource_tracker()\n"
            "print(open(f'/proc/{r._resource_tracker._pid}/status').read())\n")
    status = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60, check=True).stdout
    masks = {line.split(":")[0]: int(line.split()[1], 16) for line in status.splitlines()
             if line.startswith(("SigBlk:", "SigIgn:"))}
    assert (masks["SigBlk"] | masks["SigIgn"]) >> (signal.SIGHUP - 1) & 1, status


def test_ctrl_c_does_not_reach_the_clip_writer_processes():
    """Ctrl-C in a terminal sends SIGINT to the whole foreground process group: during
    ``simulate --clips`` each writer process printed a KeyboardInterrupt traceback before the one
    line "stopped by SIGINT". The writers run in a session of their own; their parent ends them."""
    code = ("import os, signal, time\n"
            "signal.signal(signal.SIGINT, lambda *a: None)\n"   # the parent: the CLI's handler
            "from dftl_warp.output.clip_pool import _Worker\n"
            "w = _Worker()\n"
            "time.sleep(0.5)\n"
            "os.killpg(0, signal.SIGINT)\n"                       # what the terminal does
            "w.close()\n"
            "print(w.process.wait(timeout=60))\n")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=90,
                          start_new_session=True)
    assert done.returncode == 0, done.stderr
    assert "Traceback" not in done.stderr and "KeyboardInterrupt" not in done.stderr, done.stderr
    assert done.stdout.strip() == "0", done.stdout


@pytest.mark.skipif(not Path("/proc").is_dir(), reason="needs /proc")
def test_batch_workers_start_deaf_to_ctrl_c():
    """Ctrl-C in the first second or two of a batch (SIGINT to the process group while the spawned
    workers were still importing, before they ignore SIGINT) printed their KeyboardInterrupt
    tracebacks before "stopped by SIGINT". Workers start with SIGINT blocked."""
    import multiprocessing as mp

    from dftl_warp.batch.scheduler import _Worker

    ctx = mp.get_context("spawn")
    worker = _Worker(ctx, ctx.Queue())
    try:
        status = Path(f"/proc/{worker.process.pid}/status").read_text()
    finally:
        worker.process.kill()
        worker.process.join()
    masks = {line.split(":")[0]: int(line.split()[1], 16) for line in status.splitlines()
             if line.startswith(("SigBlk:", "SigIgn:"))}
    assert (masks["SigBlk"] | masks["SigIgn"]) >> (signal.SIGINT - 1) & 1, status


def test_a_signal_during_an_import_that_swallows_it_still_stops_the_run(tmp_path, monkeypatch):
    """USD's module loader (``Tf.PreparePythonModule``) turns any exception raised while it imports
    into a warning: a Ctrl-C in the first second of a batch, while ``pxr`` loaded, printed USD
    tracebacks and the batch then ran every job to the end, exit status 0 (the handler had set
    every later signal to be ignored). A signal that comes during an import now waits for it."""
    import importlib
    import textwrap

    from dftl_warp import cli

    (tmp_path / "slow_inner.py").write_text(textwrap.dedent("""
        import os, signal, time
        os.kill(os.getpid(), signal.SIGTERM)   # arrives while this module is being imported
        time.sleep(0.2)
    """))
    (tmp_path / "swallowing_loader.py").write_text(textwrap.dedent("""
        try:                       # what USD's _LoadLibModules does with an import's exception
            import slow_inner
        except BaseException:
            swallowed = True
    """))
    monkeypatch.syspath_prepend(str(tmp_path))
    previous = cli.install_signal_handlers()
    try:
        with pytest.raises(cli.Terminated) as stopped:
            importlib.import_module("swallowing_loader")
            for _ in range(100):   # the run goes on: the deferred signal stops it here
                time.sleep(0.01)
        assert stopped.value.signum == signal.SIGTERM
        assert not hasattr(sys.modules["swallowing_loader"], "swallowed")   # the import was whole
    finally:
        cli.restore_signal_handlers(previous)
        sys.modules.pop("slow_inner", None)
        sys.modules.pop("swallowing_loader", None)


def test_a_signal_while_a_batch_worker_starts_waits_until_it_has_started():
    """SIGINT to the batch while ``Process.start`` was between the worker's fork and sending it its
    start-up data: the batch stopped there and the half-started worker printed "EOFError: Ran out
    of input". The batch's handler now runs once the worker has started, and that worker is ended."""
    import multiprocessing as mp

    from dftl_warp import cli
    from dftl_warp.batch import scheduler

    ctx = mp.get_context("spawn")
    started = []
    real_start = ctx.Process.start

    def start(process):   # the signal comes in the middle of the start
        os.kill(os.getpid(), signal.SIGINT)
        real_start(process)
        started.append(process)

    previous = cli.install_signal_handlers()
    try:
        ctx.Process.start = start
        with pytest.raises(cli.Terminated):
            scheduler._Worker(ctx, ctx.Queue())
    finally:
        ctx.Process.start = real_start
        cli.restore_signal_handlers(previous)
    assert len(started) == 1
    started[0].join(30)
    assert started[0].exitcode == -signal.SIGKILL   # ended by the batch, not by an EOFError


def test_clips_and_no_clips_in_one_job_are_refused_when_the_file_is_read(tmp_path, stage):
    """``clips = 3`` with ``no_clips = true`` (here through [defaults]) was found only once the job
    ran, after its input was read, in a line naming the output; it is now refused with the other
    bad values, in a line naming the job file and both keys."""
    path = tmp_path / "jobs.toml"
    path.write_text(f'[defaults]\nno_clips = true\n[[job]]\ninput = "{stage}"\noutput = "a.usdc"\nclips = 3\n'
                    f'[[job]]\ninput = "{stage}"\noutput = "b.usdc"\nclips = 3\nno_clips = false\n')
    jobs = load_jobs(path)
    assert jobs[0].error == f"{path}: clips and no_clips contradict each other: keep one", jobs[0].error
    assert jobs[1].error is None


def test_an_infinite_preroll_is_refused_for_what_it_breaks():
    """``preroll = inf`` said "preroll must be >= 0, got inf" (inf is >= 0); the bound it breaks is 60 s."""
    from dftl_warp.options import check_toml

    with pytest.raises(ValueError, match=r"^preroll must be at most 60, got inf$"):
        check_toml("preroll", float("inf"))
    with pytest.raises(ValueError, match=r"^preroll must be >= 0, got -inf$"):
        check_toml("preroll", float("-inf"))
