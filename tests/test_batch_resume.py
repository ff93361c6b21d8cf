"""Resumable jobs in-process: which checkpoints are used, and the job file's validation."""

from __future__ import annotations

import shutil

import numpy as np
import pytest

from batch_stages import groom_stage, hidden_files, layer_content, write_jobs
from dftl_warp.batch import checkpoint as resumable
from dftl_warp.errors import UserError
from dftl_warp.batch.jobs import Job, load_jobs
from dftl_warp.batch.checkpoint import CheckpointPolicy, JobFiles, job_lock, run_job


class Interrupt(Exception):
    pass


def interrupt_after(frames: int, also=None):
    """A progress callback that stops the job after ``frames`` frames (``also`` sees every event)."""

    def progress(event):
        if also is not None:
            also(event)
        if event["event"] == "frames" and event["done"] >= frames:
            raise Interrupt()

    return progress


@pytest.fixture(scope="module")
def stage(tmp_path_factory):
    return groom_stage(tmp_path_factory.mktemp("in") / "groom.usda", strands=60, vertices=10, end=16)


def job(stage, output, **options) -> Job:
    return Job(index=1, name="groom", input=str(stage), output=str(output), options=options)


@pytest.fixture(scope="module")
def reference(stage, tmp_path_factory):
    """Outputs of uninterrupted runs, by substeps."""
    folder = tmp_path_factory.mktemp("reference")
    outputs = {}
    for substeps in (4, 6):
        outputs[substeps] = folder / f"s{substeps}" / "groom.usdc"
        outputs[substeps].parent.mkdir()
        assert run_job(job(stage, outputs[substeps], substeps=substeps), "cpu").status == "done"
    return outputs


def _same_place(tmp_path, name):
    """An output path at the same depth as the reference outputs (so sublayer paths match)."""
    folder = tmp_path / name
    folder.mkdir()
    return folder / "groom.usdc"


def test_interrupted_job_resumes_to_the_same_output(tmp_path, stage, reference):
    out = _same_place(tmp_path, "a")
    first = run_job(job(stage, out, substeps=4), "cpu", CheckpointPolicy(every_frames=3), interrupt_after(8))
    assert first.status == "failed" and not out.exists()
    files = JobFiles(out)
    assert files.checkpoint_usd.exists() and files.checkpoint_state.exists() and not files.partial.exists()
    second = run_job(job(stage, out, substeps=4), "cpu", CheckpointPolicy(every_frames=3))
    assert second.status == "done" and second.resumed_from == 6 and second.frames == 10
    assert layer_content(out) == layer_content(reference[4])
    assert hidden_files(out.parent) == []
    third = run_job(job(stage, out, substeps=4), "cpu")
    assert third.status == "skipped" and third.frames == 0


def test_output_equals_simulate(tmp_path, stage, reference):
    from dftl_warp.simulation.simulate import simulate_usd

    out = _same_place(tmp_path, "simulate")
    simulate_usd(str(stage), str(out), substeps=4)
    assert layer_content(out) == layer_content(reference[4])


def test_checkpoint_of_other_settings_is_not_used(tmp_path, stage, reference):
    out = _same_place(tmp_path, "b")
    run_job(job(stage, out, substeps=4), "cpu", CheckpointPolicy(every_frames=2), interrupt_after(7))
    assert JobFiles(out).checkpoint_state.exists()
    changed = run_job(job(stage, out, substeps=6), "cpu", CheckpointPolicy(every_frames=2))
    assert changed.status == "done" and changed.resumed_from is None
    assert any("other settings" in n for n in changed.notes)
    assert layer_content(out) == layer_content(reference[6])
    # the output of other settings is not "complete" either
    again = run_job(job(stage, out, substeps=4), "cpu")
    assert again.status == "done" and layer_content(out) == layer_content(reference[4])


def test_checkpoint_of_an_older_format_is_not_used(tmp_path, stage, reference):
    """A checkpoint written by an older release (format 1: its clips under a frame step counted
    simulated frames) starts over instead of resuming into clips numbered the other way."""
    out = _same_place(tmp_path, "old")
    run_job(job(stage, out, substeps=4), "cpu", CheckpointPolicy(every_frames=2), interrupt_after(7))
    files = JobFiles(out)
    with np.load(files.checkpoint_state, allow_pickle=False) as data:
        state = {k: data[k] for k in data.files}
    assert int(state["format"]) == resumable.FORMAT >= 2
    state["format"] = np.array(1)
    with open(files.checkpoint_state, "wb") as f:
        np.savez(f, **state)
    again = run_job(job(stage, out, substeps=4), "cpu", CheckpointPolicy(every_frames=2))
    assert again.status == "done" and again.resumed_from is None
    assert layer_content(out) == layer_content(reference[4])


def test_output_of_simulate_is_not_taken_for_complete(tmp_path, stage, reference):
    from dftl_warp.simulation.simulate import simulate_usd

    out = _same_place(tmp_path, "c")
    simulate_usd(str(stage), str(out), substeps=6)
    assert run_job(job(stage, out, substeps=6), "cpu").status == "done"


def test_checkpoint_copy_newer_than_state(tmp_path, stage, reference):
    """Killed between the two renames of a checkpoint: the USD copy holds more frames than the
    state; the job resumes from the state and rewrites those frames identically."""
    out = _same_place(tmp_path, "d")
    files = JobFiles(out)
    saved = tmp_path / "state-at-2.npz"

    def keep_first_state(event):
        if event["event"] == "frames" and event["done"] == 3:
            shutil.copy(files.checkpoint_state, saved)

    run_job(job(stage, out, substeps=4), "cpu", CheckpointPolicy(every_frames=2), interrupt_after(7, keep_first_state))
    shutil.copy(saved, files.checkpoint_state)  # state at frame 2, USD copy at frame 6
    result = run_job(job(stage, out, substeps=4), "cpu", CheckpointPolicy(every_frames=2))
    assert result.resumed_from == 2
    assert layer_content(out) == layer_content(reference[4])


def test_damaged_checkpoint_starts_over(tmp_path, stage, reference):
    out = _same_place(tmp_path, "e")
    run_job(job(stage, out, substeps=4), "cpu", CheckpointPolicy(every_frames=2), interrupt_after(5))
    JobFiles(out).checkpoint_state.write_bytes(b"not a zip file")
    result = run_job(job(stage, out, substeps=4), "cpu")
    assert result.status == "done" and result.resumed_from is None and "unreadable" in result.notes[0]
    assert layer_content(out) == layer_content(reference[4])
    assert hidden_files(out.parent) == []


def test_a_locked_output_is_refused(tmp_path, stage, monkeypatch):
    out = _same_place(tmp_path, "f")
    monkeypatch.setattr(resumable, "LOCK_WAIT_SECONDS", 0.3)
    with job_lock(JobFiles(out).lock):
        result = run_job(job(stage, out), "cpu")
    assert result.status == "failed" and "another dftl-warp process is working on this output" in result.error
    assert not out.exists()


# -- the job file -----------------------------------------------------------------------------------


def test_job_file_paths_defaults_and_options(tmp_path):
    jobs = load_jobs(write_jobs(tmp_path / "jobs.toml", [
        {"input": "shots/a.usda", "output": "out/a.usdc", "start": 1001, "end": 1010, "prim": "/World/Hair"},
        {"input": "/abs/b.usda", "output": "out/b.usda", "name": "shot b", "substeps": 2, "device": "cuda:0,cuda:1"},
    ], defaults={"substeps": 6, "precision": "float64", "damping": 1}))
    a, b = jobs
    assert a.error is None and b.error is None
    assert a.input == str(tmp_path / "shots" / "a.usda") and a.output == str(tmp_path / "out" / "a.usdc")
    assert a.options == {"substeps": 6, "precision": "float64", "damping": 1.0, "start": 1001, "end": 1010,
                         "prims": ["/World/Hair"]}
    assert a.name == "a" and a.device is None
    assert b.name == "shot b" and b.input == "/abs/b.usda" and b.options["substeps"] == 2
    assert b.device == "cuda:0,cuda:1"


@pytest.mark.parametrize("table, message", [
    ({"output": "o.usdc"}, "missing 'input'"),
    ({"input": "a.usda"}, "missing 'output'"),
    ({"input": "a.usda", "output": "o.usdc", "substep": 2}, "unknown option 'substep' (did you mean 'substeps'?)"),
    ({"input": "a.usda", "output": "o.usdc", "substeps": 0}, "substeps must be >= 1, got 0"),
    ({"input": "a.usda", "output": "o.usdc", "substeps": 2.5}, "substeps must be an integer, got 2.5"),
    ({"input": "a.usda", "output": "o.usdc", "damping": "high"}, "damping must be a number in [0, 1]"),
    ({"input": "a.usda", "output": "o.usdc", "correction": "later"}, "correction must be one of prior, posterior"),
    ({"input": "a.usda", "output": "o.usdc", "precision": "float16"}, "precision must be one of float32, float64"),
    ({"input": "a.usda", "output": "o.usdc", "device": "gpu0"}, "device must be cpu, cuda:N"),
    ({"input": "a.usda", "output": "o.usdc", "prim": "World"}, "prim must be a prim path"),
    ({"input": "a.usda", "output": "o.usdc", "start": 10, "end": 5}, "frame range 10..5 is empty"),
    ({"input": "a.usda", "output": "o.txt"}, "must end in .usdc, .usda, .usd"),
    ({"input": "a.usda", "output": "a.usda"}, "the output would overwrite the input"),
])
def test_a_bad_job_is_refused_alone(tmp_path, table, message):
    good = {"input": "g.usda", "output": "g.usdc"}
    jobs = load_jobs(write_jobs(tmp_path / "jobs.toml", [good, table]))
    assert jobs[0].error is None
    assert jobs[1].error is not None and message in jobs[1].error, jobs[1].error
    assert jobs[1].error.startswith(str(tmp_path / "jobs.toml"))


def test_same_output_twice(tmp_path):
    jobs = load_jobs(write_jobs(tmp_path / "jobs.toml", [
        {"input": "a.usda", "output": "o.usdc"}, {"input": "b.usda", "output": "./o.usdc"}]))
    assert jobs[0].error is None and "also the output of job 1" in jobs[1].error


@pytest.mark.parametrize("text, message", [
    ("[[job]\ninput = 1", "not valid TOML"),
    ("", "no [[job]] tables"),
    ("[jobs]\ninput = 'a'", "unknown top-level key 'jobs'"),
    ("[defaults]\nsubsteps = 0\n[[job]]\ninput='a.usda'\noutput='b.usdc'", "[defaults]: substeps must be >= 1"),
])
def test_a_bad_job_file_is_refused(tmp_path, text, message):
    path = tmp_path / "jobs.toml"
    path.write_text(text)
    with pytest.raises(UserError, match=None) as info:
        load_jobs(path)
    assert message in str(info.value) and str(path) in str(info.value)
    with pytest.raises(UserError, match="no such file"):
        load_jobs(tmp_path / "none.toml")


def test_state_roundtrip_is_exact(stage):
    """save_state/load_state through an .npz keep every bit (the basis of identical resumes)."""
    from dftl_warp.simulation.simulate import Simulation, SimulationOptions
    from dftl_warp.usd.read import read_scene

    scene = read_scene(str(stage))
    sim = Simulation(scene, SimulationOptions(substeps=3), 1)
    for _ in range(3):
        sim.advance()
    saved = sim.save_state()
    other = Simulation(scene, SimulationOptions(substeps=3), 1)
    other.load_state(saved)
    for _ in range(2):
        sim.advance()
        other.advance()
    for (p, v), (q, w) in zip(sim.samples(), other.samples()):
        assert np.array_equal(p, q) and np.array_equal(v, w)


def test_a_changed_dependency_reruns_the_job(tmp_path, stage):
    """Completion covers the files the input depends on (here a sublayer), not just the input."""
    groom = tmp_path / "groom.usda"
    shutil.copy(stage, groom)
    shot = tmp_path / "shot.usda"
    shot.write_text('#usda 1.0\n(\n    subLayers = [@./groom.usda@]\n    startTimeCode = 1\n    endTimeCode = 5\n)\n')
    out = _same_place(tmp_path, "g")
    assert run_job(job(shot, out), "cpu").status == "done"
    assert run_job(job(shot, out), "cpu").status == "skipped"
    groom.write_text(groom.read_text() + "\n# edited\n")
    assert run_job(job(shot, out), "cpu").status == "done"


# -- scheduling ---------------------------------------------------------------------------------------


def test_jobs_take_the_least_busy_device():
    from dftl_warp.batch.scheduler import DevicePicker, default_workers

    picker = DevicePicker(["cuda:0", "cuda:1"])
    auto = lambda k: Job(index=k, name=str(k), input="i", output=f"o{k}.usdc")  # noqa: E731
    assert picker.take(auto(1)) == "cuda:0"
    assert picker.take(auto(2)) == "cuda:1"
    pinned = Job(index=3, name="3", input="i", output="o3.usdc", device="cuda:1")
    assert picker.take(pinned) == "cuda:1"
    picker.release("cuda:0")
    assert picker.take(auto(4)) == "cuda:0"
    assert picker.take(auto(5)) == "cuda:0"  # cuda:1 runs two
    assert default_workers(10, ["cuda:0", "cuda:1"]) == 2 and default_workers(1, ["cuda:0", "cuda:1"]) == 1


def test_ray_task_devices():
    from dftl_warp.batch.ray_cluster import task_device

    assert task_device("cpu") == ("cpu", 0)
    assert task_device("cuda:3") == ("cuda:0", 1)
    assert task_device("cuda:2,cuda:5") == ("cuda:0,cuda:1", 2)


@pytest.mark.parametrize("address, message", [
    ("127.0.0.1:1", "--ray 127.0.0.1:1: cannot connect:"), ("nonsense", "--ray nonsense: expected 'auto', 'local', HOST:PORT")])
def test_unreachable_ray_address_fails_fast(address, message):
    from dftl_warp.batch.ray_cluster import connect

    with pytest.raises(UserError, match=None) as info:
        connect(address)
    assert str(info.value).startswith(message)


def test_quality_preset_fills_unset_options(tmp_path):
    jobs = load_jobs(write_jobs(tmp_path / "jobs.toml", [
        {"input": "a.usda", "output": "a.usdc", "quality": "production", "substeps": 4},
        {"input": "b.usda", "output": "b.usdc", "solver": "pbd", "iterations": 6},
        {"input": "c.usda", "output": "c.usdc", "quality": "best"},
    ], defaults={"precision": "float64"}))
    # the preset's solver stays with ``quality`` (chains take it; prims running the elastic solver keep it)
    assert jobs[0].options == {"quality": "production", "damping": 1.0, "correction": "prior", "substeps": 4,
                               "precision": "float64"}
    assert jobs[1].options == {"precision": "float64", "solver": "pbd", "iterations": 6}
    assert "quality must be one of draft, production, reference" in jobs[2].error


@pytest.mark.parametrize("correction", ["prior", "posterior"])
def test_interleaved_state_roundtrip_and_samples_match_the_plain_layout(monkeypatch, correction):
    """The CUDA default layout (particle-major, state vectors interleaved in one buffer), forced
    here on the CPU: save_state/load_state keep every bit, and the frames equal the plain layout's."""
    from pathlib import Path

    import dftl_warp.core.model as model_module
    from dftl_warp.simulation.simulate import Simulation, SimulationOptions
    from dftl_warp.usd.read import read_scene

    scene = read_scene(str(Path(__file__).resolve().parent.parent / "scenes" / "chain.usda"))
    opts = SimulationOptions(substeps=3, correction=correction)
    plain = Simulation(scene, opts, 1)
    monkeypatch.setattr(model_module, "default_layout", lambda device: "particle-major")
    monkeypatch.setattr(model_module, "default_interleave",
                        lambda layout, device, features=False, corrections=True: 3 if corrections else 2)
    sim = Simulation(scene, opts, 1)
    assert all(g.state.storage is not None for g in sim.groups)
    assert all(g.model.layout.interleave == (3 if correction == "prior" else 2) for g in sim.groups)
    for _ in range(3):
        sim.advance()
        plain.advance()
    saved = sim.save_state()
    other = Simulation(scene, opts, 1)
    other.load_state(saved)
    for _ in range(2):
        for s in (sim, other, plain):
            s.advance()
    for (p, v), (q, w), (r, u) in zip(sim.samples(), other.samples(), plain.samples()):
        assert np.array_equal(p, q) and np.array_equal(v, w)
        assert np.array_equal(p, r) and np.array_equal(v, u)
