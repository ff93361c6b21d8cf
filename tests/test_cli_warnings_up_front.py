"""``simulate`` says what it ignores or approximates in the input before the frames run.

Before, the input's warnings (an unknown ``dftl:`` attribute, frames ``--frame-step`` leaves out, a
collider that keeps its size, a flag that does nothing here) were printed only after the whole run:
a TD starting a two-hour run learnt at its end that an attribute had been ignored. Now they come
with the device line, before the first frame, once each; with ``-q`` they come after the run, with
the other warnings, as documented. Warnings that arise while running (energy growth) still come as
they arise.
"""

from __future__ import annotations

import numpy as np
from pxr import Sdf
from test_usd_features import sphere_collider
from batch_stages import stop_after
from usd_stages import add_curves, animated_xform, chain, new_stage

from dftl_warp import cli

#: a piece of each input warning the stage and flags below give
INPUT_WARNINGS = ("dftl:bogus", "--frame-step 2: frames 1..4 end between written frames",
                  "radius is time-sampled: the collider keeps its size",
                  "--arithmetic float64 does nothing here",
                  "lie partly outside the stage's time range 1..3")


def _stage(path):
    stage = new_stage(path, start=1, end=3)
    animated_xform(stage, "/World/Head", translate={1: (0, 0, 0), 3: (0.01, 0, 0)})
    curves = add_curves(stage, "/World/Head/Hair", chain(6, 0.02, direction=(0.0, -1.0, 0.0)), [6])
    curves.GetPrim().CreateAttribute("dftl:bogus", Sdf.ValueTypeNames.Float, custom=True).Set(1.0)
    ball = sphere_collider(stage, "/World/Ball", 0.05, translate=(0.5, 0.0, 0.0))
    ball.GetRadiusAttr().Set(0.05, 1)
    ball.GetRadiusAttr().Set(0.06, 3)
    stage.Save()
    return str(path)


def _run(tmp_path, capsys, *extra):
    argv = ["simulate", _stage(tmp_path / "in.usda"), "-o", str(tmp_path / "o.usdc"), "--device", "cpu",
            "--solver", "dftl", "--end", "4", "--frame-step", "2", "--arithmetic", "float64", *extra]
    assert cli.main(argv) == 0
    return capsys.readouterr().err.splitlines()


def _where(lines, piece):
    return [k for k, line in enumerate(lines) if piece in line]


def test_input_warnings_come_before_the_frames_once_each(tmp_path, capsys):
    lines = _run(tmp_path, capsys)
    ran = _where(lines, "dftl-warp: simulating: ")
    device = _where(lines, "dftl-warp: device")
    assert ran and device, lines
    for piece in INPUT_WARNINGS:
        found = _where(lines, piece)
        assert len(found) == 1, (piece, lines)
        assert lines[found[0]].startswith("dftl-warp: warning: "), lines[found[0]]
        assert found[0] < device[0] < ran[0], (piece, lines)   # with the set-up lines, before the device line
    warned = [line for line in lines if line.startswith("dftl-warp: warning: ")]
    assert len(warned) == len(set(warned)), lines   # nothing said twice


def test_quiet_gives_the_input_warnings_once_after_the_run(tmp_path, capsys):
    lines = _run(tmp_path, capsys, "-q")
    assert all(line.startswith("dftl-warp: warning: ") for line in lines), lines
    for piece in INPUT_WARNINGS:
        assert len(_where(lines, piece)) == 1, (piece, lines)
    assert len(lines) == len(set(lines)), lines


def _ball_stage(path):
    """Hair without widths over a static ball, its head moving (10 frames): QC measures the
    penetration in default hair radii, which a note says."""
    stage = new_stage(path, start=1, end=10)
    animated_xform(stage, "/World/Head", translate={1: (0, 0, 0), 10: (0.05, 0, 0)})
    add_curves(stage, "/World/Head/Hair", chain(6, 0.02, direction=(0.0, -1.0, 0.0)), [6])
    sphere_collider(stage, "/World/Ball", 0.05, translate=(0.0, -0.3, 0.0))
    stage.Save()
    return str(path)


QC_NOTE = "no hair widths: its QC penetration is the depth below the collider surfaces"


def test_a_batch_job_gives_each_set_up_warning_once_resumed_or_not(tmp_path):
    """A batch job said the QC note after its warnings had gone out (never, in an uninterrupted job);
    a resumed job said it from its checkpoint and kept it twice in the next one: a job resumed twice
    gave it... once from a doubled record, twice. Now every job says it once."""
    from dftl_warp.batch.checkpoint import CheckpointPolicy, JobFiles, run_job
    from dftl_warp.batch.jobs import Job

    stage = _ball_stage(tmp_path / "in.usda")

    def job(output):
        return Job(index=1, name="ball", input=stage, output=str(output), options={"solver": "dftl"})

    whole = run_job(job(tmp_path / "whole.usdc"), "cpu")
    assert whole.status == "done", whole.error
    assert sum(QC_NOTE in w for w in whole.warnings) == 1, whole.warnings

    cut = tmp_path / "cut.usdc"
    seen = []
    for frames in (4, 7):   # cut twice, resumed after each
        first = run_job(job(cut), "cpu", CheckpointPolicy(every_frames=2), stop_after(frames))
        assert first.status == "failed" and JobFiles(cut).checkpoint_state.exists(), first.error
        seen.append(first.warnings)
    last = run_job(job(cut), "cpu", CheckpointPolicy(every_frames=2))
    assert last.status == "done" and last.resumed_from is not None, last.error
    for warnings in (*seen, last.warnings):
        assert sum(QC_NOTE in w for w in warnings) == 1, warnings
    assert sorted(last.warnings) == sorted(whole.warnings), (last.warnings, whole.warnings)


def test_the_summary_keeps_the_input_warnings_apart_from_the_set_up_lines(tmp_path):
    """``Summary.start_notes`` was documented as the clean start's and the preroll's lines but held
    the frame-range warning too (and the QC's notes). Now it holds the set-up's lines its docstring
    lists; the input's warnings are in ``warnings`` only, ahead of them."""
    from dftl_warp.simulation.simulate import simulate_usd

    summary = simulate_usd(_ball_stage(tmp_path / "in.usda"), str(tmp_path / "o.usdc"), device="cpu",
                           solver="dftl", end=12, preroll=0.1)
    ranged = [w for w in summary.warnings if "lie partly outside the stage's time range 1..10" in w]
    assert len(ranged) == 1 and ranged[0] not in summary.start_notes, summary
    assert [n.split(":")[0] for n in summary.start_notes] == ["preroll", "/World/Head/Hair"], summary.start_notes
    assert QC_NOTE in summary.start_notes[1], summary.start_notes
    assert summary.warnings[-len(summary.start_notes):] == summary.start_notes, summary


def test_a_batch_job_says_what_its_options_do_not_do_as_simulate_does(tmp_path):
    """A job's ``iterations`` and ``arithmetic`` that no prim's solver takes, and a quality preset that
    leaves prims with widths on the elastic solver, were said by simulate and silently ignored by
    batch. Now a job says them as simulate does, once (resumed too: the note comes with its checkpoint)."""
    from dftl_warp.batch.checkpoint import CheckpointPolicy, run_job
    from dftl_warp.batch.jobs import Job
    from dftl_warp.simulation.simulate import simulate_usd

    plain = _ball_stage(tmp_path / "in.usda")
    options = {"solver": "dftl", "iterations": 3, "arithmetic": "float64"}
    said = simulate_usd(plain, str(tmp_path / "s.usdc"), device="cpu", **options).warnings
    unused = [w for w in said if "does nothing here" in w]
    assert len(unused) == 2, said
    job = run_job(Job(index=1, name="j", input=plain, output=str(tmp_path / "j.usdc"), options=options), "cpu")
    assert job.status == "done" and [w for w in job.warnings if "does nothing here" in w] == unused, job.warnings

    stage = new_stage(tmp_path / "rods.usda", start=1, end=6)
    add_curves(stage, "/World/Hair", chain(5, 0.02, direction=(0.0, -1.0, 0.0)), [5], widths=1e-4, bending=True)
    stage.Save()

    def rods(**kwargs):
        return run_job(Job(index=1, name="rods", input=str(tmp_path / "rods.usda"), output=str(tmp_path / "r.usdc"),
                           options={"quality": "draft", "substeps": 2}), "cpu", **kwargs)

    cut = rods(policy=CheckpointPolicy(every_frames=2), progress=stop_after(4))
    resumed = rods()
    assert cut.status == "failed" and resumed.status == "done" and resumed.resumed_from is not None, resumed.error
    for warnings in (cut.warnings, resumed.warnings):
        assert sum(w.startswith("quality draft: 1 prim with widths keeps the elastic solver") for w in warnings) == 1, \
            warnings


def test_a_collider_approximated_while_running_is_a_run_warning(tmp_path, capsys):
    """A mesh collider approximated mid-run came out as Python's two-line warning
    ('.../device.py:187: ColliderApproximationWarning: /World/Grow: ...' and a line of source),
    naming no file, kept in no summary. Now it is one 'dftl-warp: warning: FILE: ...' line when it
    arises, once, and one of the run's warnings. (Written for a mesh deformed past its signed
    distance field's grid; since deforming meshes move inside the frame, a mesh moving faster than
    its field's band is handed to the exact queries instead, and that is the warning it gives.)"""
    from pxr import UsdGeom, UsdPhysics, Vt
    from test_features import box_mesh

    from dftl_warp.simulation.simulate import simulate_usd

    path = tmp_path / "grow.usda"
    stage = new_stage(path, start=1, end=4)
    add_curves(stage, "/World/Hair", chain(6, 0.02, direction=(0.0, -1.0, 0.0), origin=(0.0, 0.5, 0.0)), [6])
    points, faces = box_mesh((0.04, 0.04, 0.04))
    mesh = UsdGeom.Mesh.Define(stage, "/World/Grow")   # 4 cm, then 1.6 m, 3.2 m and 4.8 m across
    for f in range(1, 5):
        mesh.CreatePointsAttr().Set(Vt.Vec3fArray.FromNumpy((points * (1 + 40 * (f - 1))).astype(np.float32)), f)
    mesh.CreateFaceVertexCountsAttr(Vt.IntArray([3] * len(faces)))
    mesh.CreateFaceVertexIndicesAttr(Vt.IntArray([int(i) for i in faces.reshape(-1)]))
    UsdPhysics.CollisionAPI.Apply(mesh.GetPrim())
    mesh.GetPrim().CreateAttribute("dftl:collisionSdf", Sdf.ValueTypeNames.Bool, custom=True).Set(True)
    stage.Save()
    assert cli.main(["simulate", str(path), "-o", str(tmp_path / "o.usdc"), "--solver", "dftl"]) == 0
    lines = capsys.readouterr().err.splitlines()
    assert all(line.startswith("dftl-warp: ") for line in lines), lines
    grid = f"dftl-warp: warning: {path}: /World/Grow: its points move up to "
    found = [k for k, line in enumerate(lines) if line.startswith(grid)]
    assert len(found) == 1 and found[0] > _where(lines, "dftl-warp: device")[0], lines
    summary = simulate_usd(str(path), str(tmp_path / "p.usdc"), solver="dftl", device="cpu")
    assert [w for w in summary.run_warnings if "its points move up to" in w] == [lines[found[0]][20:]], summary
