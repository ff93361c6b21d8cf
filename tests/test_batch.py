"""dftl-warp batch: interrupted batches finish with identical outputs; bad jobs fail alone; Ray."""

from __future__ import annotations

import os
import signal
import subprocess
import time
from pathlib import Path

import pytest

from batch_stages import batch_command, groom_stage, hidden_files, layer_content, run_batch, write_jobs


def _session_processes(sid: int) -> list[int]:
    """Processes of the session ``sid`` still alive (zombies excluded)."""
    alive = []
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            stat = (entry / "stat").read_text()
        except OSError:
            continue
        fields = stat[stat.rindex(")") + 2:].split()
        if int(fields[3]) == sid and fields[0] != "Z":
            alive.append(int(entry.name))
    return alive


@pytest.fixture(scope="module")
def inputs(tmp_path_factory):
    folder = tmp_path_factory.mktemp("inputs")
    return {
        "a": groom_stage(folder / "a.usda", strands=20, vertices=8, end=6),
        "b": groom_stage(folder / "b.usda", strands=2000, vertices=16, end=80, seed=1),
        "c": groom_stage(folder / "c.usda", strands=300, vertices=12, end=40, seed=2),
    }


def _three_jobs(folder: Path, inputs) -> Path:
    folder.mkdir(parents=True)
    rel = lambda p: os.path.relpath(p, folder)  # noqa: E731
    return write_jobs(folder / "jobs.toml", [
        {"input": rel(inputs["a"]), "output": "out/a.usdc"},
        {"input": rel(inputs["b"]), "output": "out/b.usdc", "name": "long"},
        {"input": rel(inputs["c"]), "output": "out/c.usda", "substeps": 4, "damping": 0.9},
    ])


@pytest.mark.skipif(not Path("/proc").is_dir(), reason="needs /proc to follow the killed batch's processes")
def test_sigkilled_batch_reruns_to_identical_outputs(tmp_path, inputs):
    """A 3-job batch SIGKILLed half-way (one job done, one checkpointed) and run again finishes
    every job: the done one is skipped, the checkpointed one resumes, and every output equals
    that of an uninterrupted run bit for bit; no temporary or checkpoint file is left."""
    reference = _three_jobs(tmp_path / "reference", inputs)
    done = run_batch(reference, "--workers", "2")
    assert done.returncode == 0, done.stderr
    assert "3 done" in done.stdout

    jobs = _three_jobs(tmp_path / "interrupted", inputs)
    out = jobs.parent / "out"
    batch = subprocess.Popen(batch_command(jobs, "--workers", "2", "--checkpoint-frames", "2"),
                             cwd=jobs.parent, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                             start_new_session=True)
    try:
        deadline = time.monotonic() + 120
        while not ((out / "a.usdc").exists() and (out / ".b.usdc.dftl-checkpoint.npz").exists()):
            assert batch.poll() is None, "the batch ended before it could be interrupted"
            assert time.monotonic() < deadline, "no checkpoint appeared"
            time.sleep(0.01)
        os.kill(batch.pid, signal.SIGKILL)  # the batch process only: its workers must follow
        batch.wait()
        deadline = time.monotonic() + 20
        while _session_processes(batch.pid) and time.monotonic() < deadline:
            time.sleep(0.05)
        assert _session_processes(batch.pid) == [], "workers outlived the killed batch"
    finally:
        try:
            os.killpg(batch.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
    assert not (out / "b.usdc").exists(), "the long job finished before the kill: nothing was interrupted"
    for name in ("a.usdc", "c.usda"):  # whatever was there is whole
        if (out / name).exists():
            assert layer_content(out / name) == layer_content(reference.parent / "out" / name)

    rerun = run_batch(jobs, "--workers", "2", "--checkpoint-frames", "2")
    assert rerun.returncode == 0, rerun.stderr
    assert "[1/3] a: skipped: already complete" in rerun.stderr
    assert "[2/3] long: done" in rerun.stderr and "resumed after frame" in rerun.stderr
    for name in ("a.usdc", "b.usdc", "c.usda"):
        assert layer_content(out / name) == layer_content(reference.parent / "out" / name), name
    assert hidden_files(jobs.parent) == []
    assert hidden_files(reference.parent) == []


def test_bad_jobs_fail_alone(tmp_path, inputs):
    """Missing input, a syntax error, a bad option name and a bad value each fail their job with
    one line; the good job completes; the exit status says not all succeeded."""
    broken = tmp_path / "broken.usda"
    broken.write_text("#usda 1.0\ndef BasisCurves \"Hair\" {\n  int[] curveVertexCounts = [2\n}\n")
    jobs = write_jobs(tmp_path / "jobs.toml", [
        {"input": "missing.usda", "output": "out/missing.usdc"},
        {"input": str(inputs["a"]), "output": "out/good.usdc", "end": 4},
        {"input": str(broken), "output": "out/broken.usdc"},
        {"input": str(inputs["a"]), "output": "out/typo.usdc", "substep": 2},
        {"input": str(inputs["a"]), "output": "out/damping.usdc", "damping": 1.5},
    ])
    result = run_batch(jobs, "--workers", "2")
    assert result.returncode == 1
    errors = [line for line in result.stderr.splitlines() if line.startswith("dftl-warp: error:")]
    assert len(errors) == 4, result.stderr
    assert "job 1 (missing)" in errors[0] and "missing.usda" in errors[0]
    assert "job 3 (broken)" in errors[1] and "broken.usda" in errors[1]
    assert "unknown option 'substep' (did you mean 'substeps'?)" in errors[2]
    assert "damping must be in [0, 1], got 1.5" in errors[3]
    assert "Traceback" not in result.stderr
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == ["good.usdc"]
    assert "1 done, 0 skipped, 4 failed" in result.stdout


def test_ray_runs_the_batch_on_a_local_instance(tmp_path, inputs):
    """--ray local: the same jobs as Ray tasks give the outputs of a local run; a bad job fails alone."""
    specs = [
        {"input": str(inputs["a"]), "output": "out/a.usdc"},
        {"input": str(inputs["c"]), "output": "out/c.usdc", "end": 12, "device": "cpu"},
        {"input": str(tmp_path / "missing.usda"), "output": "out/missing.usdc"},
    ]
    for folder in ("local", "ray"):
        (tmp_path / folder).mkdir()
    local = write_jobs(tmp_path / "local" / "jobs.toml", specs)
    on_ray = write_jobs(tmp_path / "ray" / "jobs.toml", specs)
    result = run_batch(on_ray, "--ray", "local")
    assert result.returncode == 1, result.stderr
    assert "2 done, 0 skipped, 1 failed" in result.stdout, result.stdout + result.stderr
    assert "missing.usda: no such file" in result.stderr
    assert run_batch(local, "--workers", "1").returncode == 1
    for name in ("a.usdc", "c.usdc"):
        assert layer_content(on_ray.parent / "out" / name) == layer_content(local.parent / "out" / name)
    assert hidden_files(on_ray.parent) == []


def test_ray_not_installed_is_one_line(tmp_path, inputs):
    blocker = tmp_path / "no_ray" / "ray"
    blocker.mkdir(parents=True)
    (blocker / "__init__.py").write_text("raise ImportError('ray blocked for this test')\n")
    jobs = write_jobs(tmp_path / "jobs.toml", [{"input": str(inputs["a"]), "output": "out/a.usdc"}])
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(blocker.parent), os.environ.get("PYTHONPATH", "")]))
    result = subprocess.run(batch_command(jobs, "--ray", "auto"), capture_output=True, text=True, env=env, timeout=120)
    assert result.returncode == 2
    assert result.stderr.strip() == "dftl-warp: error: --ray: Ray is not installed; install it with: pip install 'dftl-warp[ray]'"
    assert not (tmp_path / "out").exists()


def test_a_job_writing_a_layer_its_input_uses_fails_alone(tmp_path, inputs):
    """A job whose output is a sublayer of its input fails with one line naming both files, and
    the layer is left as it was (as `simulate` refuses it); the other job completes."""
    import shutil

    hair = tmp_path / "hair.usda"
    shutil.copy(inputs["a"], hair)
    top = tmp_path / "top.usda"
    top.write_text('#usda 1.0\n(\n    subLayers = [@./hair.usda@]\n)\n')
    before = hair.read_bytes()
    jobs = write_jobs(tmp_path / "jobs.toml", [
        {"input": str(top), "output": str(hair)},
        {"input": str(inputs["a"]), "output": "out/good.usdc", "end": 3},
    ])
    result = run_batch(jobs)
    assert result.returncode == 1
    errors = [line for line in result.stderr.splitlines() if line.startswith("dftl-warp: error:")]
    assert len(errors) == 1 and f"the output would overwrite {hair}, which the input {top} uses" in errors[0], \
        result.stderr
    assert hair.read_bytes() == before and (tmp_path / "out" / "good.usdc").is_file()


def test_a_job_on_a_device_that_is_not_here_names_the_job_files_key(tmp_path, inputs):
    """The job file says ``device = "cuda:7"``: its one line names ``device``, not a ``--device``
    flag nobody typed; the API's keyword is named the same way."""
    import dftl_warp as dw
    from dftl_warp.errors import UserError

    jobs = write_jobs(tmp_path / "jobs.toml", [
        {"input": str(inputs["a"]), "output": "out/a.usdc", "end": 2, "device": "cuda:7"},
    ])
    result = run_batch(jobs)
    assert result.returncode == 1
    errors = [line for line in result.stderr.splitlines() if line.startswith("dftl-warp: error:")]
    assert len(errors) == 1 and "job 1 (a): device cuda:7: not available here" in errors[0], result.stderr
    assert "--device" not in result.stderr and "Traceback" not in result.stderr
    with pytest.raises(UserError, match="^device cuda:7: not available here"):
        dw.simulate_usd(inputs["a"], tmp_path / "api.usdc", end=2, device="cuda:7")


def test_a_job_whose_output_is_another_jobs_input_fails_and_the_groom_survives(tmp_path, inputs):
    """Job 1 writes the file job 2 reads (directly, or a sublayer of it): run in either order it
    would destroy job 2's groom. Job 1 fails with one line; the groom is untouched; job 2 runs."""
    import shutil

    victim = tmp_path / "victim.usda"
    shutil.copy(inputs["a"], victim)
    before = victim.read_bytes()
    top = tmp_path / "top.usda"
    top.write_text('#usda 1.0\n(\n    subLayers = [@./under.usda@]\n)\n')
    shutil.copy(inputs["b"], tmp_path / "under.usda")
    under = (tmp_path / "under.usda").read_bytes()
    jobs = write_jobs(tmp_path / "jobs.toml", [
        {"input": str(inputs["c"]), "output": "victim.usda", "end": 2},
        {"input": "victim.usda", "output": "out/v.usdc", "end": 2},
        {"input": str(inputs["c"]), "output": "under.usda", "end": 2, "name": "sub"},
        {"input": "top.usda", "output": "out/t.usdc", "start": 1, "end": 2},
    ])
    result = run_batch(jobs)
    assert result.returncode == 1
    errors = [line for line in result.stderr.splitlines() if line.startswith("dftl-warp: error:")]
    assert len(errors) == 2, result.stderr
    assert "job 1 (victim)" in errors[0] and "would overwrite the input of job 2 (v)" in errors[0]
    assert "job 3 (sub)" in errors[1] and "would overwrite a layer the input of job 4 (t) uses" in errors[1]
    assert victim.read_bytes() == before and (tmp_path / "under.usda").read_bytes() == under
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == ["t.usdc", "v.usdc"]
