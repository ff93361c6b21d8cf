"""What a batch tells the user: each job's warnings (as simulate prints them), the job file's
messages for a bad ``check`` and for options jobs do not take, and what an interrupted batch
leaves next to its outputs (checkpoints, never a partial file or a lock)."""

from __future__ import annotations

import os
import signal
import subprocess
import time
from pathlib import Path

import pytest
from pxr import Sdf, Usd

from batch_stages import batch_command, groom_stage, hidden_files, run_batch, write_jobs
from usd_stages import add_curves, chain, new_stage
from dftl_warp.batch.checkpoint import run_job
from dftl_warp.batch.jobs import Job, load_jobs
from dftl_warp.errors import UserError

TYPO = "unknown attribute dftl:dampng (did you mean dftl:damping?)"


@pytest.fixture(scope="module")
def typo_stage(tmp_path_factory):
    """A small groom whose hair prim has a misspelt dftl: attribute."""
    path = groom_stage(tmp_path_factory.mktemp("typo") / "typo.usda", strands=4, vertices=6, end=4)
    stage = Usd.Stage.Open(str(path))
    stage.GetPrimAtPath("/World/Head/Hair").CreateAttribute("dftl:dampng", Sdf.ValueTypeNames.Float).Set(0.5)
    stage.GetRootLayer().Save()
    return path


@pytest.fixture(scope="module")
def unstable_stage(tmp_path_factory):
    """DFTL with s = 0 at many substeps pumps energy into a horizontal chain (test_energy_warning)."""
    path = tmp_path_factory.mktemp("unstable") / "chain.usda"
    stage = new_stage(path, start=1, end=24)
    add_curves(stage, "/World/Hair", chain(64, 0.005, direction=(1.0, 0.0, 0.0)), [64])
    stage.Save()
    return path


def _warnings(stderr: str) -> list[str]:
    return [line for line in stderr.splitlines() if line.startswith("dftl-warp: warning:")]


# -- warnings ---------------------------------------------------------------------------------------


def test_run_job_keeps_the_input_and_energy_warnings(tmp_path, typo_stage, unstable_stage):
    """run_job hands back (and sends as events) the warnings simulate prints: the input's unknown
    attribute and the run's energy growth."""
    events = []
    typo = run_job(Job(index=1, name="typo", input=str(typo_stage), output=str(tmp_path / "a.usdc")), "cpu",
                   progress=events.append)
    assert typo.status == "done" and len(typo.warnings) == 1 and TYPO in typo.warnings[0], typo.warnings
    assert [e["text"] for e in events if e["event"] == "warning"] == typo.warnings
    grown = run_job(Job(index=2, name="en", input=str(unstable_stage), output=str(tmp_path / "b.usdc"),
                        options={"solver": "dftl", "damping": 0.0, "substeps": 40}), "cpu")
    assert grown.status == "done"
    assert len(grown.warnings) == 1 and "energy grew" in grown.warnings[0] and "use s = 1" in grown.warnings[0]
    skipped = run_job(Job(index=1, name="typo", input=str(typo_stage), output=str(tmp_path / "a.usdc")), "cpu")
    assert skipped.status == "skipped" and skipped.warnings == typo.warnings  # the input is still misspelt


@pytest.mark.parametrize("workers", ["1", "2"])
def test_batch_prints_each_jobs_warnings_with_its_name(tmp_path, typo_stage, unstable_stage, workers):
    """Warnings raised in the worker processes reach stderr once each, as
    ``dftl-warp: warning: job N (NAME): ...``; the table counts them; a clean job has none."""
    jobs = write_jobs(tmp_path / "jobs.toml", [
        {"input": str(typo_stage), "output": "out/typo.usdc"},
        {"input": str(unstable_stage), "output": "out/en.usdc", "solver": "dftl", "damping": 0.0, "substeps": 40},
        {"input": str(unstable_stage), "output": "out/clean.usdc", "end": 3},
    ])
    result = run_batch(jobs, "--workers", workers)
    assert result.returncode == 0, result.stderr
    lines = _warnings(result.stderr)
    assert len(lines) == 2, result.stderr
    typo = next(line for line in lines if "job 1 (typo)" in line)
    assert typo.startswith("dftl-warp: warning: job 1 (typo): ") and TYPO in typo and str(typo_stage) in typo
    grown = next(line for line in lines if "job 2 (en)" in line)
    assert "energy grew" in grown and "unstable" in grown
    assert "Traceback" not in result.stderr
    rows = {line.split("│")[2].strip(): line.split("│")[-2].strip() for line in result.stdout.splitlines()
            if line.count("│") > 8 and line.split("│")[1].strip().isdigit()}
    assert rows == {"typo": "1", "en": "1", "clean": "-"}, result.stdout


def test_quiet_batch_keeps_the_warnings_in_its_summary(tmp_path, typo_stage):
    jobs = write_jobs(tmp_path / "jobs.toml", [{"input": str(typo_stage), "output": "out/typo.usdc"}])
    result = run_batch(jobs, "--quiet")
    assert result.returncode == 0, result.stderr
    assert _warnings(result.stderr) == [f"dftl-warp: warning: job 1 (typo): {w}" for w in
                                        run_job(Job(index=1, name="typo", input=str(typo_stage),
                                                    output=str(tmp_path / "out" / "typo.usdc")), "cpu").warnings]
    assert "[1/1]" not in result.stderr  # no progress lines


# -- the job file -----------------------------------------------------------------------------------


@pytest.mark.parametrize("check, message", [
    ("strech<1e-3", "check 'strech<1e-3': each gate is METRIC<LIMIT with METRIC one of stretch, penetration, "
                    "speed, energy, nan"),
    ("stretch<e", "check 'stretch<e': 'e' is not a number"),
    ("stretch<inf", "check 'stretch<inf': the limit of stretch must be finite"),
    (5, "check must be a string, got 5"),
])
def test_a_bad_check_is_refused_in_the_gates_words(tmp_path, check, message):
    """As simulate --check and the API say it, naming the job file and the key (not the flag);
    the job is refused before anything runs, the other job is not."""
    path = write_jobs(tmp_path / "jobs.toml", [{"input": "in.usda", "output": "o.usdc", "check": check},
                                               {"input": "in.usda", "output": "p.usdc", "check": "stretch<1e-3"}])
    bad, good = load_jobs(path)
    assert bad.error == f"{path}: {message}"
    assert "--check" not in bad.error
    assert good.error is None and good.options["check"] == "stretch<1e-3"


@pytest.mark.parametrize("key, value, what", [("output", "  ", "layer to write"), ("output", "", "layer to write"),
                                              ("input", " ", "stage to simulate")])
def test_a_blank_path_is_refused_as_an_empty_path_naming_the_job(tmp_path, capsys, key, value, what):
    """``output = "  "`` named the job '  ' ("job 1 (  ): ...: output    must end in .usdc, ...");
    now the job keeps a name and the line says the path is empty."""
    table = {"input": "in.usda", "output": "o.usdc", key: value}
    path = write_jobs(tmp_path / "jobs.toml", [table, {"input": "in.usda", "output": "p.usdc", "name": " "}])
    bad, good = load_jobs(path)
    assert (bad.name, good.name) == (("job1" if key == "output" else "o"), "p")
    assert bad.error == f"{path}: {key} = {value!r} is an empty path: give the {what}"
    assert good.error is None


def test_the_api_and_the_job_file_agree_on_a_bad_gate():
    from dftl_warp.output.qc import parse_gates

    with pytest.raises(UserError) as api:
        parse_gates("strech<1e-3")
    gate_words = str(api.value).split(": ", 1)[1]
    assert gate_words.startswith("each gate is METRIC<LIMIT")


@pytest.mark.parametrize("key, value, flag", [("tolerance", 0.1, "--tolerance"), ("guides", "50%", "--guides"),
                                              ("guide_method", "fps", "--guide-method"),
                                              ("guides_output", "binding", "--guides-output")])
def test_simulate_only_options_are_refused_with_a_reason(tmp_path, key, value, flag):
    path = write_jobs(tmp_path / "jobs.toml", [{"input": "in.usda", "output": "o.usdc", key: value}])
    (job,) = load_jobs(path)
    assert job.error == (f"{path}: option {key!r} ({flag}) is not available in batch jobs: run that input with "
                         f"dftl-warp simulate (docs/batch.md lists the options jobs take)")
    defaults = write_jobs(tmp_path / "defaults.toml", [{"input": "in.usda", "output": "o.usdc"}], {key: value})
    with pytest.raises(UserError, match=rf"\[defaults\]: option '{key}' \({flag}\) is not available in batch jobs"):
        load_jobs(defaults)


def test_the_documented_job_options_are_the_ones_taken():
    """docs/batch.md lists exactly the keys a job takes, and the simulate options it does not."""
    from dftl_warp.batch.jobs import JOB_KEYS, SIMULATE_ONLY, _simulate_options

    text = (Path(__file__).parent.parent / "docs" / "batch.md").read_text()
    section = text.split("## JOBS.toml")[1].split("## Running locally")[0]
    for key in [*JOB_KEYS, *_simulate_options(), *SIMULATE_ONLY]:
        assert f"`{key}`" in section, key


# -- interruptions ----------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def long_stage(tmp_path_factory):
    return groom_stage(tmp_path_factory.mktemp("long") / "long.usda", strands=2000, vertices=16, end=80, seed=1)


def _start_until_checkpoint(folder: Path, stage, *args):
    jobs = write_jobs(folder / "jobs.toml", [{"input": str(stage), "output": "out/long.usdc"}])
    batch = subprocess.Popen(batch_command(jobs, "--workers", "1", "--checkpoint-frames", "2", *args),
                             cwd=folder, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                             start_new_session=True)
    deadline = time.monotonic() + 120
    while not (folder / "out" / ".long.usdc.dftl-checkpoint.npz").exists():
        assert batch.poll() is None, batch.communicate()
        assert time.monotonic() < deadline, "no checkpoint appeared"
        time.sleep(0.01)
    return jobs, batch


def _worker_pids(parent: int) -> list[int]:
    pids = []
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                stat = (entry / "stat").read_text()
                cmdline = (entry / "cmdline").read_bytes()
            except OSError:
                continue
            if int(stat[stat.rindex(")") + 2:].split()[1]) == parent and b"spawn_main" in cmdline:
                pids.append(int(entry.name))
    return pids


CHECKPOINT_FILES = [".long.usdc.dftl-checkpoint.npz", ".long.usdc.dftl-checkpoint.usdc"]


@pytest.mark.skipif(not Path("/proc").is_dir(), reason="needs /proc")
@pytest.mark.parametrize("how", ["sigterm-batch", "sigkill-worker"])
def test_an_interrupted_job_leaves_its_checkpoint_only_and_resumes(tmp_path, long_stage, how):
    """SIGTERM to the batch (exit 143) or SIGKILL to its worker (the job fails): the partial file
    and the lock are removed, the checkpoint stays, and a rerun resumes and leaves nothing hidden."""
    jobs, batch = _start_until_checkpoint(tmp_path, long_stage)
    try:
        if how == "sigterm-batch":
            batch.send_signal(signal.SIGTERM)
        else:
            deadline = time.monotonic() + 30
            while not _worker_pids(batch.pid):
                assert time.monotonic() < deadline
                time.sleep(0.05)
            for pid in _worker_pids(batch.pid):
                os.kill(pid, signal.SIGKILL)
        _, err = batch.communicate(timeout=120)
    finally:
        if batch.poll() is None:
            os.killpg(batch.pid, signal.SIGKILL)
    if how == "sigterm-batch":
        assert batch.returncode == 143 and "stopped by SIGTERM" in err, err
    else:
        assert batch.returncode == 1, err
        assert "job 1 (long)" in err and "worker process died (killed by signal 9)" in err, err
    assert not (tmp_path / "out" / "long.usdc").exists()
    assert hidden_files(tmp_path) == CHECKPOINT_FILES
    rerun = run_batch(jobs, "--workers", "1")
    assert rerun.returncode == 0, rerun.stderr
    assert "resumed after frame" in rerun.stderr
    assert hidden_files(tmp_path) == []
