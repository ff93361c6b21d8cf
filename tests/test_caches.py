"""Caches for pipelines (issue 21, docs/caches.md): output options, provenance, per-frame QC and
``--check``, ``dftl-warp diff``, value clips. CPU, small grooms."""

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from pxr import Sdf, Usd, UsdGeom
from usd_stages import add_curves, chain, new_stage

from dftl_warp import cli
from dftl_warp.output import provenance
from dftl_warp.output.qc import ATTRIBUTES, QCError, parse_gates
from dftl_warp.simulation.simulate import simulate_usd

ROOT = Path(__file__).resolve().parent.parent


def groom(path, strands=4, vertices=6, end=8):
    stage = new_stage(path, end=end)
    pts = np.concatenate([chain(vertices, 0.1, origin=(0.0, 0.0, 0.2 * s)) for s in range(strands)])
    add_curves(stage, "/World/Hair", pts, [vertices] * strands)
    add_curves(stage, "/World/Fur", pts + 5.0, [vertices] * strands)
    stage.Save()
    return Path(path)


def points(path, prim="/World/Hair"):
    stage = Usd.Stage.Open(str(path))
    attr = UsdGeom.BasisCurves(stage.GetPrimAtPath(prim)).GetPointsAttr()
    return {t: np.asarray(attr.Get(t)) for t in attr.GetTimeSamples()}


# -- 1. output options ----------------------------------------------------------------------------


def test_frame_step_and_no_velocities_through_cli_api_and_same_points(tmp_path):
    src = groom(tmp_path / "in.usda")
    simulate_usd(src, tmp_path / "all.usdc", device="cpu")
    assert cli.main(["simulate", str(src), "-o", str(tmp_path / "step.usdc"), "--frame-step", "3",
                     "--no-velocities", "--quiet", "--device", "cpu"]) == 0
    every, step = points(tmp_path / "all.usdc"), points(tmp_path / "step.usdc")
    assert sorted(step) == [1.0, 4.0, 7.0]  # every 3rd frame written, every frame simulated
    for t in step:
        assert np.array_equal(step[t], every[t])
    layer = Sdf.Layer.FindOrOpen(str(tmp_path / "step.usdc"))
    assert not layer.GetAttributeAtPath("/World/Hair.velocities")
    assert (layer.startTimeCode, layer.endTimeCode) == (1.0, 7.0)
    # the API checks them against the options table
    with pytest.raises(ValueError, match="frame_step must be >= 1"):
        simulate_usd(src, tmp_path / "x.usdc", frame_step=0)


def test_output_options_in_the_batch_toml(tmp_path):
    from dftl_warp.batch.checkpoint import run_job
    from dftl_warp.batch.jobs import load_jobs

    src = groom(tmp_path / "in.usda")
    (tmp_path / "jobs.toml").write_text('[[job]]\ninput = "in.usda"\noutput = "o.usdc"\nframe_step = 2\n'
                                        'no_velocities = true\n[[job]]\ninput = "in.usda"\noutput = "p.usdc"\n'
                                        'frame_step = 0\n')
    jobs = load_jobs(tmp_path / "jobs.toml")
    assert "frame_step must be >= 1" in jobs[1].error
    result = run_job(jobs[0], "cpu")
    assert result.status == "done", result.error
    assert sorted(points(tmp_path / "o.usdc")) == [1.0, 3.0, 5.0, 7.0]
    assert not Sdf.Layer.FindOrOpen(str(tmp_path / "o.usdc")).GetAttributeAtPath("/World/Hair.velocities")
    assert src.exists()


# -- 2. provenance --------------------------------------------------------------------------------


def test_provenance_record_and_info(tmp_path, capsys):
    from dftl_warp.batch.checkpoint import input_fingerprint

    src = groom(tmp_path / "in.usda")
    out = tmp_path / "o.usdc"
    assert cli.main(["simulate", str(src), "-o", str(out), "--quiet", "--device", "cpu", "--substeps", "3",
                     "--damping", "0.5", "--quality", "draft"]) == 0
    record = provenance.read(out)
    assert record["version"] == __import__("dftl_warp").__version__
    assert "--substeps 3" in record["command"] and record["date"].startswith("20")
    assert record["device"] == {"cpu": record["device"]["cpu"]}
    assert record["input"]["path"] == str(src.resolve())
    assert record["input"]["sha256"] == input_fingerprint(src)[str(src.resolve())]
    group = record["groups"]["group0"]
    assert group["substeps"] == 3 and group["damping"] == 0.5 and group["quality"] == "draft"
    for key in ("solver", "correction", "precision", "tolerance", "features", "prims"):
        assert key in group
    assert record["output"]["frame_step"] == 1
    capsys.readouterr()
    assert cli.main(["info", str(out)]) == 0
    text = capsys.readouterr().out
    assert "provenance" in text and record["input"]["sha256"] in text and "substeps" in text
    # its own output's simulated frames are not "an animated groom" to warn about
    assert "time-sampled" not in text, text
    assert cli.main(["info", str(out), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["provenance"]["groups"]["group0"]["substeps"] == 3


# -- 3. QC ----------------------------------------------------------------------------------------


def test_qc_time_samples_per_prim(tmp_path):
    src = groom(tmp_path / "in.usda")
    out = tmp_path / "o.usdc"
    simulate_usd(src, out, device="cpu", frame_step=2)
    stage = Usd.Stage.Open(str(out))
    for prim in ("/World/Hair", "/World/Fur"):
        qc = stage.GetPrimAtPath("/dftl_qc/" + prim.strip("/").replace("/", "_"))
        assert qc.GetAttribute("dftl:qc:prim").Get() == prim
        stretch = qc.GetAttribute(ATTRIBUTES["stretch"])
        assert stretch.GetTimeSamples() == [1.0, 3.0, 5.0, 7.0]
        assert 0 <= stretch.Get(7) < 1e-3
        assert qc.GetAttribute(ATTRIBUTES["speed"]).Get(1) == 0.0  # at rest
        assert qc.GetAttribute(ATTRIBUTES["speed"]).Get(7) > 0.1  # falling
        assert qc.GetAttribute(ATTRIBUTES["nan"]).Get(7) == 0
        assert np.isfinite(qc.GetAttribute(ATTRIBUTES["energy"]).Get(7))
        assert qc.GetAttribute(ATTRIBUTES["penetration"]).Get(7) == 0.0  # no colliders: nothing to penetrate
    # energy per unit mass: kinetic - g.x summed over the free particles, by hand at rest
    pts = points(out)[1.0].reshape(4, 6, 3)[:, 1:]
    assert stage.GetPrimAtPath("/dftl_qc/World_Hair").GetAttribute(ATTRIBUTES["energy"]).Get(1) == \
        pytest.approx(9.80665 * pts[..., 1].sum(), rel=1e-5)


def test_check_gate_fails_with_status_3_naming_frame_and_prim_and_leaves_no_output(tmp_path, capsys):
    src = groom(tmp_path / "in.usda")
    out = tmp_path / "o.usdc"
    code = cli.main(["simulate", str(src), "-o", str(out), "--quiet", "--device", "cpu",
                     "--check", "stretch<1, speed<0.2"])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 3 and len(err) == 1
    assert "speed<0.2 broken at frame 2 by /World/Hair" in err[0]
    assert not out.exists() and not list(tmp_path.glob(".o.usdc*"))
    assert cli.main(["simulate", str(src), "-o", str(out), "--quiet", "--device", "cpu",
                     "--check", "stretch<1e-3,penetration<0.05,nan<1"]) == 0
    assert out.exists()
    assert parse_gates("stretch<1e-3, penetration<0.05") == {"stretch": 1e-3, "penetration": 0.05}
    capsys.readouterr()
    with pytest.raises(SystemExit) as exc:
        cli.main(["simulate", str(src), "-o", str(out), "--check", "wobble<1"])
    assert exc.value.code == 2 and "METRIC<LIMIT" in capsys.readouterr().err


def test_batch_reports_a_broken_gate(tmp_path):
    from dftl_warp.batch.checkpoint import run_job
    from dftl_warp.batch.jobs import load_jobs

    groom(tmp_path / "in.usda")
    (tmp_path / "jobs.toml").write_text('[[job]]\ninput = "in.usda"\noutput = "o.usdc"\ncheck = "speed<0.2"\n')
    result = run_job(load_jobs(tmp_path / "jobs.toml")[0], "cpu")
    assert result.status == "failed" and "speed<0.2 broken at frame 2 by /World/Hair" in result.error
    assert not (tmp_path / "o.usdc").exists()


# -- 4. diff --------------------------------------------------------------------------------------


def test_diff_command(tmp_path, capsys):
    src = groom(tmp_path / "in.usda")
    simulate_usd(src, tmp_path / "a.usdc", device="cpu")
    simulate_usd(src, tmp_path / "b.usdc", device="cpu")
    simulate_usd(src, tmp_path / "c.usdc", device="cpu", damping=0.5)
    capsys.readouterr()
    assert cli.main(["diff", str(tmp_path / "a.usdc"), str(tmp_path / "b.usdc")]) == 0
    assert "within tolerance" in capsys.readouterr().out
    assert cli.main(["diff", str(tmp_path / "a.usdc"), str(tmp_path / "c.usdc"), "--tolerance", "1e-6"]) == 1
    out = capsys.readouterr().out
    assert "first difference beyond 1e-06 stage units: frame 2, /World/Hair" in out
    assert cli.main(["diff", str(tmp_path / "a.usdc"), str(tmp_path / "c.usdc"), "--json"]) == 1
    d = json.loads(capsys.readouterr().out)
    row = d["prims"]["/World/Fur"][-1]
    a, c = points(tmp_path / "a.usdc", "/World/Fur")[8.0], points(tmp_path / "c.usdc", "/World/Fur")[8.0]
    dist = np.linalg.norm(a.astype(float) - c.astype(float), axis=1)
    assert row["max"] == pytest.approx(dist.max()) and row["rms"] == pytest.approx(np.sqrt((dist ** 2).mean()))
    assert row["max_relative"] == pytest.approx(dist.max() / 0.5, rel=1e-3)  # strands 5 x 0.1 long
    assert d["first_beyond"]["time"] == 2.0
    assert cli.main(["diff", str(tmp_path / "a.usdc"), str(tmp_path / "c.usdc"), "--tolerance", "1",
                     "--relative"]) == 0
    capsys.readouterr()
    assert cli.main(["diff", str(tmp_path / "a.usdc"), str(tmp_path / "nothing.usdc")]) == 2
    assert capsys.readouterr().err.count("\n") == 1


# -- 5. value clips -------------------------------------------------------------------------------


def test_clips_compose_bitwise_to_the_single_layer_output_and_validate(tmp_path):
    from test_usd_write import _errors

    src = ROOT / "scenes" / "default.usda"
    simulate_usd(src, tmp_path / "single.usdc", end=8, device="cpu")
    assert cli.main(["simulate", str(src), "-o", str(tmp_path / "clips.usdc"), "--end", "8", "--clips", "3",
                     "--quiet", "--device", "cpu"]) == 0
    folder = tmp_path / "clips_clips"
    assert sorted(p.name for p in folder.iterdir()) == ["clip.0000.usdc", "clip.0001.usdc", "clip.0002.usdc",
                                                       "topology.usdc"]
    a, b = Usd.Stage.Open(str(tmp_path / "single.usdc")), Usd.Stage.Open(str(tmp_path / "clips.usdc"))
    prim = "/World/Head/Hair"
    assert Usd.ClipsAPI(b.GetPrimAtPath(prim)).GetClipAssetPaths("default")
    for name in ("points", "velocities", "extent"):
        x, y = a.GetPrimAtPath(prim).GetAttribute(name), b.GetPrimAtPath(prim).GetAttribute(name)
        assert x.GetTimeSamples() == y.GetTimeSamples() == [float(t) for t in range(1, 9)]
        for t in [*range(0, 10), 2.5, 3.5]:
            assert np.array_equal(np.asarray(x.Get(t)), np.asarray(y.Get(t))), (name, t)
    assert provenance.read(tmp_path / "clips.usdc")["output"]["clips"] == 3
    assert _errors(tmp_path / "clips.usdc") == set()
    assert not list(tmp_path.glob(".*"))  # no partial files left


_KILLED_JOB = """
import os, signal, sys
from dftl_warp.batch.checkpoint import CheckpointPolicy, run_job
from dftl_warp.batch.jobs import Job

def progress(event):  # SIGKILL itself half-way, past a few finished chunks
    if event["event"] == "frames" and event["done"] >= int(sys.argv[3]):
        os.kill(os.getpid(), signal.SIGKILL)

job = Job(index=1, name="clips", input=sys.argv[1], output=sys.argv[2], options={"clips": 3, "end": 16})
run_job(job, "cpu", CheckpointPolicy(every_seconds=0), progress)
"""


def test_batch_clips_resume_per_chunk_after_sigkill_to_identical_output(tmp_path):
    from batch_stages import hidden_files, layer_content
    from dftl_warp.batch.checkpoint import JobFiles, run_job
    from dftl_warp.batch.jobs import Job

    src = groom(tmp_path / "in.usda", end=16)
    out = {}
    for name in ("ref", "killed"):
        (tmp_path / name).mkdir()
        out[name] = tmp_path / name / "shot.usdc"
    make = lambda o: Job(index=1, name="clips", input=str(src), output=str(o), options={"clips": 3, "end": 16})  # noqa: E731
    assert run_job(make(out["ref"]), "cpu").status == "done"
    killed = subprocess.run([sys.executable, "-c", _KILLED_JOB, str(src), str(out["killed"]), "11"],
                            cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert killed.returncode == -9, killed.stderr
    files = JobFiles(out["killed"])
    assert not out["killed"].exists() and files.checkpoint_state.exists()
    chunks = tmp_path / "killed" / ".shot_clips.dftl-partial"
    assert len(list(chunks.glob("clip.*.usdc"))) >= 3  # chunks 0..2 whole (frames 1-9), checkpointed at 10
    again = run_job(make(out["killed"]), "cpu")
    assert again.status == "done", again.error
    assert again.resumed_from == 9 and again.frames == 7  # from the last complete chunk (frames 1-9)
    assert layer_content(out["killed"]) == layer_content(out["ref"])
    ref_clips, new_clips = (sorted((o.parent / "shot_clips").iterdir()) for o in (out["ref"], out["killed"]))
    assert [p.name for p in ref_clips] == [p.name for p in new_clips]
    for a, b in zip(ref_clips, new_clips):
        assert layer_content(a) == layer_content(b), a.name
    for prim in ("/World/Hair", "/World/Fur"):
        ref, new = points(out["ref"], prim), points(out["killed"], prim)
        assert sorted(ref) == sorted(new) == [float(t) for t in range(1, 17)]
        assert all(np.array_equal(ref[t], new[t]) for t in ref)
    assert hidden_files(tmp_path / "killed") == [] and "dftl_warp_clips" not in Sdf.Layer.FindOrOpen(
        str(out["killed"])).customLayerData


def test_clips_are_chosen_automatically_above_the_measured_size(tmp_path):
    from types import SimpleNamespace

    from dftl_warp.output.clips import AUTO_MIN_FRAMES, AUTO_MIN_POINTS, auto_clips, auto_minimum

    # the measured crossovers: 2 writer processes (the 2-core VM), 8 (the 16-core H200 machine)
    assert auto_minimum(2) == (320_000, 24) and auto_minimum(8) == (160_000, 16)
    big = SimpleNamespace(curves=[SimpleNamespace(num_points=AUTO_MIN_POINTS)])
    small = SimpleNamespace(curves=[SimpleNamespace(num_points=AUTO_MIN_POINTS - 1)])
    assert auto_clips(big, AUTO_MIN_FRAMES, "a.usdc") == -(-AUTO_MIN_FRAMES // 8)  # 8 chunks at least
    assert auto_clips(big, 240, "a.usd") == 30
    assert auto_clips(big, AUTO_MIN_FRAMES - 1, "a.usdc") is None
    assert auto_clips(small, 1000, "a.usdc") is None
    assert auto_clips(big, 1000, "a.usda") is None  # clips are crate layers


def test_a_failing_clip_writer_is_one_line_exit_2_and_no_output(tmp_path, capsys, monkeypatch):
    from dftl_warp.output import clips

    def broken(path, *args):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(clips, "_author_clip", broken)
    src = groom(tmp_path / "in.usda")
    assert cli.main(["simulate", str(src), "-o", str(tmp_path / "o.usdc"), "--clips", "2", "--quiet",
                     "--device", "cpu"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "No space left on device" in err[0] and "clip.0000.usdc" in err[0], err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["in.usda"]


def test_clips_of_several_writer_processes_fsyncd_equal_the_single_layer_output(tmp_path, monkeypatch):
    from dftl_warp.output import clip_pool, clips

    monkeypatch.setattr(clips, "WRITERS", 3)  # chunks spread over three processes, two prims per frame
    monkeypatch.setattr(clips, "FSYNC", True)
    src = groom(tmp_path / "in.usda")
    simulate_usd(src, tmp_path / "one.usdc", device="cpu", no_clips=True)
    simulate_usd(src, tmp_path / "clips.usdc", device="cpu", clips=2)
    assert not clip_pool._EARLY  # the processes started early were the writer's
    assert sorted(p.name for p in (tmp_path / "clips_clips").iterdir()) == [
        *(f"clip.{i:04d}.usdc" for i in range(4)), "topology.usdc"]
    a, b = Usd.Stage.Open(str(tmp_path / "one.usdc")), Usd.Stage.Open(str(tmp_path / "clips.usdc"))
    for prim in ("/World/Hair", "/World/Fur"):
        for name in ("points", "velocities", "extent"):
            x, y = a.GetPrimAtPath(prim).GetAttribute(name), b.GetPrimAtPath(prim).GetAttribute(name)
            assert x.GetTimeSamples() == y.GetTimeSamples() == [float(t) for t in range(1, 9)]
            for t in range(1, 9):
                assert np.array_equal(np.asarray(x.Get(t)), np.asarray(y.Get(t))), (prim, name, t)


def test_a_clip_writer_process_that_dies_is_one_line_and_no_output(tmp_path):
    from dftl_warp.errors import UserError
    from dftl_warp.output.clips import create_clips
    from dftl_warp.usd.read import read_scene

    src = groom(tmp_path / "in.usda")
    scene = read_scene(str(src))
    frame = [(np.zeros((c.num_points, 3), np.float32), np.zeros((c.num_points, 3), np.float32)) for c in scene.curves]
    with pytest.raises(UserError, match="clip writer process ended unexpectedly") as error:
        with create_clips(tmp_path / "o.usdc", scene, frames=(1, 8), clip_frames=2) as writer:
            writer.write_frame(1, frame)
            for worker in writer._pool.workers:
                worker.process.kill()
                worker.process.wait()
            for f in range(2, 9):
                writer.write_frame(f, frame)
            writer.commit()
    assert "\n" not in str(error.value)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["in.usda"]


def test_clip_writer_processes_follow_the_cores_and_the_memory():
    from dftl_warp.output.clip_pool import MAX_WRITERS, slot_count, writer_count

    assert [writer_count(n) for n in (1, 2, 4, 16, 64)] == [1, 2, 4, min(16, MAX_WRITERS), MAX_WRITERS]
    assert slot_count(8, 40 << 20) == 18  # two frames per writer and two for the frame loop
    assert slot_count(8, 1 << 40) == 2  # frames larger than the memory: two slots still


def test_automatic_clips_and_no_clips(tmp_path, monkeypatch):
    from dftl_warp.output import clips

    monkeypatch.setattr(clips, "AUTO_MIN_POINTS", 10)  # this groom (48 points) counts as large
    monkeypatch.setattr(clips, "AUTO_MIN_FRAMES", 4)
    src = groom(tmp_path / "in.usda")
    simulate_usd(src, tmp_path / "one.usdc", device="cpu", no_clips=True)
    simulate_usd(src, tmp_path / "auto.usdc", device="cpu")
    assert not (tmp_path / "one_clips").exists()
    assert sorted(p.name for p in (tmp_path / "auto_clips").iterdir()) == [  # 8 frames, 8 chunks at least
        *(f"clip.{i:04d}.usdc" for i in range(8)), "topology.usdc"]
    assert provenance.read(tmp_path / "auto.usdc")["output"]["clips"] == 1
    one, auto = points(tmp_path / "one.usdc"), points(tmp_path / "auto.usdc")
    assert sorted(one) == sorted(auto) and all(np.array_equal(one[t], auto[t]) for t in one)
    assert cli.main(["simulate", str(src), "-o", str(tmp_path / "x.usdc"), "--clips", "2", "--no-clips",
                     "--quiet", "--device", "cpu"]) == 2


def test_clips_with_frame_step_hold_clips_written_frames_through_simulate_and_batch(tmp_path):
    from dftl_warp.batch.checkpoint import CheckpointPolicy, run_job
    from dftl_warp.batch.jobs import Job

    src = groom(tmp_path / "in.usda", end=8)
    simulate_usd(src, tmp_path / "one.usdc", device="cpu", frame_step=2, no_clips=True)
    assert cli.main(["simulate", str(src), "-o", str(tmp_path / "c.usdc"), "--frame-step", "2", "--clips", "2",
                     "--quiet", "--device", "cpu"]) == 0
    job = Job(index=1, name="b", input=str(src), output=str(tmp_path / "b.usdc"), options={"clips": 2, "frame_step": 2})
    run_job(job, "cpu", CheckpointPolicy(every_seconds=0), lambda event: None)
    one = points(tmp_path / "one.usdc")
    assert sorted(one) == [1.0, 3.0, 5.0, 7.0]
    for name in ("c", "b"):  # frames 1, 3 | 5, 7: two clips of 2 written frames (it was 4 of one)
        assert sorted(p.name for p in (tmp_path / f"{name}_clips").iterdir()) == [
            "clip.0000.usdc", "clip.0001.usdc", "topology.usdc"], name
        assert [Sdf.Layer.FindOrOpen(str(tmp_path / f"{name}_clips" / f"clip.000{i}.usdc")).ListAllTimeSamples()
                for i in (0, 1)] == [[1.0, 3.0], [5.0, 7.0]]
        got = points(tmp_path / f"{name}.usdc")
        assert sorted(got) == sorted(one) and all(np.array_equal(one[t], got[t]) for t in one), name


def test_shot_usdc_and_shot_usd_never_share_their_clips_folder(tmp_path, capsys):
    from dftl_warp.batch.jobs import load_jobs

    src = groom(tmp_path / "in.usda")
    assert cli.main(["simulate", str(src), "-o", str(tmp_path / "x.usdc"), "--clips", "2", "--quiet",
                     "--device", "cpu"]) == 0
    before = points(tmp_path / "x.usdc")
    layers = {p.name: p.read_bytes() for p in (tmp_path / "x_clips").iterdir()}
    capsys.readouterr()
    # x.usd's clips go into x_clips/ too: they replaced x.usdc's animation without a word
    assert cli.main(["simulate", str(src), "-o", str(tmp_path / "x.usd"), "--clips", "3", "--substeps", "1",
                     "--quiet", "--device", "cpu"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "Traceback" not in err
    assert f"{tmp_path / 'x.usd'}: its value clips would replace those of {tmp_path / 'x.usdc'}" in err
    assert not (tmp_path / "x.usd").exists() and not list(tmp_path.glob(".*"))
    assert {p.name: p.read_bytes() for p in (tmp_path / "x_clips").iterdir()} == layers
    after = points(tmp_path / "x.usdc")
    assert all(np.array_equal(before[t], after[t]) for t in before)
    # a single layer beside it, or clips of another stem, are fine
    assert cli.main(["simulate", str(src), "-o", str(tmp_path / "x.usda"), "--quiet", "--device", "cpu"]) == 0
    # batch: both jobs may write clips (asked for, or automatic) into the one folder
    (tmp_path / "jobs.toml").write_text('[[job]]\ninput = "in.usda"\noutput = "o/s.usdc"\n'
                                        '[[job]]\ninput = "in.usda"\noutput = "o/s.usd"\nclips = 2\n'
                                        '[[job]]\ninput = "in.usda"\noutput = "o/t.usdc"\nno_clips = true\n'
                                        '[[job]]\ninput = "in.usda"\noutput = "o/t.usd"\n')
    jobs = load_jobs(tmp_path / "jobs.toml")
    assert [j.error is None for j in jobs] == [True, False, True, True]
    assert jobs[1].error.endswith("output o/s.usd would write its value clips into s_clips/, as the output of "
                                  "job 1 does: give it another name")


def test_a_single_layer_over_a_clips_output_removes_its_clips(tmp_path):
    src = groom(tmp_path / "in.usda")
    for clips in ("3", "2"):  # clips over clips: the folder holds the new chunks only
        assert cli.main(["simulate", str(src), "-o", str(tmp_path / "x.usdc"), "--clips", clips, "--quiet",
                         "--device", "cpu"]) == 0
    assert len(list((tmp_path / "x_clips").iterdir())) == 5
    (tmp_path / "y_clips").mkdir()  # a folder of that name no output uses is not ours to remove
    for name in ("x", "y"):
        simulate_usd(src, tmp_path / f"{name}.usdc", device="cpu", no_clips=True)
    # x_clips was left beside the new single layer, which no longer names it: stale frames
    assert not (tmp_path / "x_clips").exists() and (tmp_path / "y_clips").is_dir()
    one = points(tmp_path / "x.usdc")
    assert sorted(one) == [float(t) for t in range(1, 9)]
