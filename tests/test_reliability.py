"""Issue 18: concurrent runs, farm signals, frame ranges, one-line failures of render/info, blank
renders, progress in logs, output folders, the default device, and a quiet import.

Signals, pipes and concurrency go through the CLI in fresh processes."""

from __future__ import annotations

import errno
import os
import signal
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np
import pytest
from pxr import Sdf, Usd, UsdGeom

from dftl_warp import cli
from dftl_warp.errors import UserError
from usd_stages import add_curves, chain, new_stage

#: subprocesses stay on the CPU whatever the machine has (CI has no GPU)
ENV = {**os.environ, "DFTL_WARP_DEVICE": "cpu"}


def cli_command(*args) -> list[str]:
    return [sys.executable, "-m", "dftl_warp", *map(str, args)]


def run_cli(*args, timeout=120) -> subprocess.CompletedProcess:
    return subprocess.run(cli_command(*args), capture_output=True, text=True, timeout=timeout, env=ENV)


def leftovers(folder) -> list[str]:
    """Hidden files dftl-warp leaves next to its outputs (temporary, partial, lock)."""
    return sorted(p.name for p in Path(folder).rglob(".*"))


def one_line(err: str) -> str:
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in err, err
    return lines[0]


def hair_stage(path, *, strands=4, vertices=6, start=1, end=96):
    stage = new_stage(path, start=start, end=end)
    pts = np.concatenate([chain(vertices, 0.05, origin=(0.2 * k, 1.0, 0.0)) for k in range(strands)])
    add_curves(stage, "/World/Hair", pts, [vertices] * strands, widths=0.01)
    stage.GetRootLayer().Save()
    return Path(path)


@pytest.fixture
def scene(tmp_path):
    return hair_stage(tmp_path / "in" / "hair.usda")


def last_points(path):
    stage = Usd.Stage.Open(str(path))
    assert stage is not None
    curves = UsdGeom.BasisCurves(stage.GetPrimAtPath("/World/Hair"))
    pts = np.asarray(curves.GetPointsAttr().Get(stage.GetEndTimeCode()))
    assert pts.shape == (24, 3) and np.isfinite(pts).all()
    return pts


# -- 1. concurrent runs ----------------------------------------------------------------------------


def test_parallel_simulates_of_one_output_leave_a_readable_file(scene, tmp_path):
    """N=4 `simulate` processes on one output, three times: each either succeeds or fails with
    the one-line lock message; every success leaves a readable output and nothing else."""
    out = tmp_path / "out" / "hair.usdc"
    for attempt in range(3):
        args = [scene, "-o", out, "--end", "40", "--substeps", "40", "--quiet"]
        with ThreadPoolExecutor(4) as pool:
            results = list(pool.map(lambda _: run_cli("simulate", *args), range(4)))
        codes = [r.returncode for r in results]
        assert 0 in codes, [r.stderr for r in results]
        for r in results:
            if r.returncode == 0:
                last_points(out)
            else:
                assert r.returncode == 2, r.stderr
                assert one_line(r.stderr) == f"dftl-warp: error: {out}: another dftl-warp run is writing it"
        assert leftovers(out.parent) == [], attempt


def test_a_locked_output_is_refused_at_once(scene, tmp_path):
    from dftl_warp.output.lock import lock_path, output_lock
    from dftl_warp.simulation.simulate import simulate_usd

    out = tmp_path / "o.usdc"
    with output_lock(lock_path(out)):
        start = time.monotonic()
        with pytest.raises(UserError, match="another dftl-warp run is writing it"):
            simulate_usd(str(scene), str(out), end=3)
        assert time.monotonic() - start < 5
    assert not out.exists() and leftovers(tmp_path) == []


def test_writers_of_one_output_stream_into_their_own_files(scene, tmp_path):
    from dftl_warp.output.usd import UsdWriter, partial_path
    from dftl_warp.usd.read import read_scene

    s = read_scene(str(scene))
    out = tmp_path / "o.usdc"
    a, b = UsdWriter.create(out, s, frames=(1, 2)), UsdWriter.create(out, s, frames=(1, 2))
    assert a.partial != b.partial and a.partial.parent == out.parent == b.partial.parent
    assert partial_path(out) not in (a.partial, b.partial)  # the fixed name is batch's (resumable)
    a.abort(), b.abort()
    resumable = UsdWriter.create(out, s, frames=(1, 2), keep_partial=True)
    assert resumable.partial == partial_path(out)
    resumable.keep_partial = False
    resumable.abort()
    assert leftovers(tmp_path) == [".in"] or leftovers(tmp_path) == []


# -- 2. signals -------------------------------------------------------------------------------------


@pytest.mark.parametrize("signum", [signal.SIGTERM, signal.SIGHUP, signal.SIGINT])
def test_signals_remove_the_partial_file(tmp_path, signum):
    scene = hair_stage(tmp_path / "in.usda", strands=1, vertices=21)
    out = tmp_path / "out" / "o.usdc"
    p = subprocess.Popen(cli_command("simulate", scene, "-o", out, "--substeps", "4000", "--quiet"),
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=ENV)
    try:
        deadline = time.monotonic() + 60
        while not list(out.parent.glob(".o.usdc.dftl-partial*")) if out.parent.exists() else True:
            assert p.poll() is None, p.communicate()
            assert time.monotonic() < deadline
            time.sleep(0.02)
        time.sleep(0.2)  # inside the frame loop
        p.send_signal(signum)
        _, err = p.communicate(timeout=60)
    finally:
        if p.poll() is None:
            p.kill()
    assert p.returncode == 128 + signum, err
    assert one_line(err) == f"dftl-warp: stopped by {signal.Signals(signum).name}"
    assert not out.exists() and leftovers(out.parent) == []


# -- 3. frame ranges --------------------------------------------------------------------------------


def test_simulated_range_is_the_output_range_and_render_refuses_frames_without_samples(scene, tmp_path):
    out = tmp_path / "o.usdc"
    r = run_cli("simulate", scene, "-o", out, "--start", 1001, "--end", 1004, "--quiet")
    assert r.returncode == 0, r.stderr
    layer = Sdf.Layer.FindOrOpen(str(out))
    assert (layer.startTimeCode, layer.endTimeCode) == (1001, 1004)
    frames = tmp_path / "frames"
    code = cli.main(["render", str(out), "--start", "1", "--end", "96", "-o", str(frames / "h.####.png"), "-q"])
    assert code == 2 and not frames.exists()
    code = cli.main(["render", str(out), "--start", "1003", "--end", "1005", "-o", str(frames / "h.####.png"), "-q"])
    assert code == 2 and not frames.exists()
    code = cli.main(["render", str(out), "--start", "1001", "--end", "1004", "--resolution", "16x16", "--spp", "1",
                     "-o", str(frames / "h.####.png"), "-q"])
    assert code == 0 and len(list(frames.iterdir())) == 4


def test_render_names_the_first_frame_without_samples(scene, tmp_path, capsys):
    from dftl_warp.simulation.simulate import simulate_usd

    out = tmp_path / "o.usdc"
    simulate_usd(str(scene), str(out), start=1, end=3)
    code = cli.main(["render", str(out), "--start", "2", "--end", "9", "-o", str(tmp_path / "f.####.png"), "-q"])
    err = one_line(capsys.readouterr().err)
    assert code == 2 and "frame 4 has no samples" in err and "/World/Hair.points" in err and "1..3" in err


def test_a_static_stage_renders_over_a_range(scene, tmp_path):
    """No time-sampled points anywhere: the static groom is what a user expects, every frame."""
    frames = tmp_path / "frames"
    assert cli.main(["render", str(scene), "--start", "1", "--end", "2", "--resolution", "16x16", "--spp", "1",
                     "-o", str(frames / "h.####.png"), "-q"]) == 0
    assert len(list(frames.iterdir())) == 2


# -- 4. render and info failures --------------------------------------------------------------------


def test_render_into_a_file_as_folder_is_one_line(scene, tmp_path, capsys):
    (tmp_path / "afile").write_text("x")
    code = cli.main(["render", str(scene), "--frame", "1", "-o", str(tmp_path / "afile" / "x.png"), "-q"])
    assert code == 2 and "cannot write" in one_line(capsys.readouterr().err)


def test_render_into_an_unwritable_folder_is_one_line(scene, tmp_path, capsys, monkeypatch):
    # CI runs as root, which writes into read-only folders anyway: the folder's permission check
    # is made to answer as it does for an ordinary user (os.access: no write permission)
    folder = tmp_path / "ro"
    folder.mkdir()
    real_access = os.access
    monkeypatch.setattr(os, "access", lambda p, mode, *a, **k: False if Path(p) == folder and mode & os.W_OK
                        else real_access(p, mode, *a, **k))
    code = cli.main(["render", str(scene), "--frame", "1", "-o", str(folder / "x.png"), "-q"])
    assert code == 2 and "not writable" in one_line(capsys.readouterr().err)
    assert list(folder.iterdir()) == []


def test_render_onto_a_full_disk_is_one_line(scene, tmp_path, capsys, monkeypatch):
    from PIL import Image

    def full(self, *a, **k):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    monkeypatch.setattr(Image.Image, "save", full)
    out = tmp_path / "o" / "x.png"
    code = cli.main(["render", str(scene), "--frame", "1", "--resolution", "16x16", "--spp", "1", "-o", str(out), "-q"])
    err = one_line(capsys.readouterr().err)
    assert code == 2 and os.strerror(errno.ENOSPC) in err and str(out) in err
    assert list(out.parent.iterdir()) == []


def test_video_without_the_extra_fails_before_rendering(scene, tmp_path, capsys, monkeypatch):
    from dftl_warp.render.renderer import Renderer

    def never(*a, **k):
        raise AssertionError("rendered a frame")

    monkeypatch.setattr(Renderer, "render", never)
    monkeypatch.setitem(sys.modules, "imageio_ffmpeg", None)
    code = cli.main(["render", str(scene), "--start", "1", "--end", "3", "-o", str(tmp_path / "x.mp4"), "-q"])
    assert code == 2 and "imageio-ffmpeg" in one_line(capsys.readouterr().err)
    monkeypatch.setitem(sys.modules, "imageio", None)
    monkeypatch.setitem(sys.modules, "imageio.v3", None)
    code = cli.main(["render", str(scene), "--start", "1", "--end", "3", "-o", str(tmp_path / "x.gif"), "-q"])
    assert code == 2 and "needs imageio" in one_line(capsys.readouterr().err)
    assert not (tmp_path / "x.mp4").exists() and not (tmp_path / "x.gif").exists()


def test_info_into_a_closed_pipe_has_no_traceback(scene):
    p = subprocess.Popen(cli_command("info", "--json", scene), stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                         env=ENV)
    p.stdout.close()  # the reader went away before anything was written (`| head` that ended)
    err = p.stderr.read().decode()
    p.wait(timeout=60)
    assert err == "" and p.returncode == 141, err
    # through a shell pipe too
    r = subprocess.run(" ".join(map(str, cli_command("info", "--json", scene))) + " | head -n 1",
                       shell=True, capture_output=True, text=True, env=ENV, timeout=60)
    assert r.stdout == "{\n" and "Traceback" not in r.stderr and r.stderr == ""


# -- 8. blank renders -------------------------------------------------------------------------------


def test_an_empty_stage_does_not_render(tmp_path, capsys):
    empty = tmp_path / "empty.usda"
    stage = new_stage(empty)
    stage.GetRootLayer().Save()
    code = cli.main(["render", str(empty), "-o", str(tmp_path / "x.png"), "-q"])
    assert code == 2 and "nothing to render" in one_line(capsys.readouterr().err)
    assert not (tmp_path / "x.png").exists()


def test_an_output_whose_input_moved_does_not_render(tmp_path):
    scene = hair_stage(tmp_path / "in" / "hair.usda")
    out = tmp_path / "out" / "o.usdc"
    assert run_cli("simulate", scene, "-o", out, "--end", "3", "--quiet").returncode == 0
    scene.rename(tmp_path / "in" / "moved.usda")
    r = run_cli("render", out, "-o", tmp_path / "x.png", "-q")
    assert r.returncode == 2 and "sublayer" in one_line(r.stderr) and "hair.usda" in r.stderr
    assert not (tmp_path / "x.png").exists()


# -- 9. progress in logs ----------------------------------------------------------------------------


def test_progress_in_a_log_is_lines_not_a_bar(scene, tmp_path):
    r = run_cli("simulate", scene, "-o", tmp_path / "o.usdc", "--end", "50")
    assert r.returncode == 0, r.stderr
    assert "\r" not in r.stderr
    lines = [x for x in r.stderr.splitlines() if "simulating:" in x]
    assert 5 <= len(lines) <= 11 and lines[-1].startswith("dftl-warp: simulating: 50/50 frames (100%)"), r.stderr


def test_line_progress_every_tenth_or_minute():
    from dftl_warp.output.progress import LineProgress

    now = [0.0]
    lines = []

    class Sink:
        def write(self, text):
            lines.append(text)

        def flush(self):
            pass

    bar = LineProgress(1000, "x", "frames", Sink(), clock=lambda: now[0])
    for _ in range(1000):
        bar.update(1)
    assert sum("/1000" in t for t in lines) == 10
    lines.clear()
    bar = LineProgress(10 ** 6, "x", "frames", Sink(), clock=lambda: now[0])
    for _ in range(5):
        now[0] += 61
        bar.update(1)
    assert sum("/1000000" in t for t in lines) == 5


def test_batch_progress_in_a_log_is_lines(tmp_path):
    from dftl_warp.batch.jobs import Job
    from dftl_warp.batch.scheduler import Reporter
    from rich.console import Console
    import io

    reporter = Reporter(1, console=Console(file=io.StringIO()))
    assert reporter.progress is None  # not a terminal
    job = Job(index=1, name="j", input="a", output="b", options={})
    import contextlib

    err = io.StringIO()
    with contextlib.redirect_stderr(err):
        reporter.queued(job, "cpu")
        reporter.event(job, {"event": "start", "total": 100, "first": 1, "last": 100, "resumed_from": None})
        for done in range(1, 101):
            reporter.event(job, {"event": "frames", "done": done})
    text = err.getvalue()
    assert "\r" not in text and text.count("frames (") == 10 and "[1/1] j: 100/100 frames (100%)" in text


# -- 10. output folders -----------------------------------------------------------------------------


def test_simulate_and_render_create_their_folders(scene, tmp_path):
    out = tmp_path / "a" / "b" / "o.usdc"
    r = run_cli("simulate", scene, "-o", out, "--end", "2", "--quiet")
    assert r.returncode == 0 and out.exists(), r.stderr
    png = tmp_path / "c" / "d" / "x.png"
    assert cli.main(["render", str(out), "--resolution", "16x16", "--spp", "1", "-o", str(png), "-q"]) == 0
    assert png.exists()


def test_simulate_into_a_file_as_folder_is_one_line(scene, tmp_path):
    (tmp_path / "afile").write_text("x")
    r = run_cli("simulate", scene, "-o", tmp_path / "afile" / "o.usdc", "--end", "2")
    assert r.returncode == 2 and "is not a folder" in one_line(r.stderr)


# -- 11. default device -----------------------------------------------------------------------------


def test_default_device(monkeypatch):
    import warp as wp

    from dftl_warp.core import devices

    monkeypatch.delenv(devices.DEVICE_ENV, raising=False)
    monkeypatch.setattr(wp, "get_cuda_device_count", lambda: 0)
    assert devices.default_device() == "cpu"
    monkeypatch.setattr(wp, "get_cuda_device_count", lambda: 2)
    assert devices.default_device() == "cuda:0"
    monkeypatch.setenv(devices.DEVICE_ENV, "cpu")
    assert devices.default_device() == "cpu"
    assert devices.resolve_device("cpu") == "cpu" and devices.resolve_device(None) == "cpu"
    assert devices.parse_devices(" cuda:0, cuda:1") == ["cuda:0", "cuda:1"]
    with pytest.raises(UserError, match="empty device name"):
        devices.parse_devices("cuda:0,,cuda:1")
    assert devices.device_line("cpu") == "dftl-warp: device cpu"


def test_render_says_which_device_runs(scene, tmp_path, capsys):
    from dftl_warp.core.devices import default_device

    assert cli.main(["render", str(scene), "--resolution", "8x8", "--spp", "1", "-o", str(tmp_path / "x.png")]) == 0
    err = capsys.readouterr().err
    assert f"dftl-warp: device {default_device()}" in err


# -- 12. quieter ------------------------------------------------------------------------------------


def test_import_prints_nothing_and_does_not_initialise_warp():
    code = ("import dftl_warp, dftl_warp.cli, dftl_warp.commands.render, dftl_warp.commands.info\n"
            "import warp._src.context as c\nassert c.runtime is None, 'warp initialised at import'\n")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=ENV, timeout=120)
    assert r.returncode == 0 and r.stdout == "" and r.stderr == "", r.stderr


def test_cli_prints_no_warp_banner(scene, tmp_path):
    r = run_cli("info", scene)
    assert r.returncode == 0 and "Warp " not in r.stdout + r.stderr and r.stderr == "", r.stderr


def test_licence_is_an_spdx_string():
    try:
        import tomllib
    except ImportError:  # pragma: no cover
        import tomli as tomllib
    project = tomllib.loads((Path(__file__).parents[1] / "pyproject.toml").read_text())
    assert project["project"]["license"] == "Apache-2.0"


def test_describe_quality():
    from dftl_warp.simulation.quality import describe_quality

    assert describe_quality("production").startswith(
        "dftl-warp: quality production: solver dftl, 256 substeps per frame, float32, damping 1, prior correction; "
        "measured 0.0169 of the strand length")
    line = describe_quality("draft", {"substeps": 4, "solver": None})
    assert "4 substeps per frame (given; the preset has 16 substeps per frame)" in line
    assert "measured" not in line  # an override leaves the measured setting
    assert "solver rattle, 16 substeps per frame, float32; measured 0.000264" in describe_quality("reference")


def test_sigterm_to_a_batch_keeps_its_checkpoints(tmp_path):
    """A batch stopped by SIGTERM exits 143 at once; the job's checkpoint stays (a batch's
    partial work is kept on purpose) and the next run resumes from it."""
    from batch_stages import batch_command, groom_stage, hidden_files, write_jobs

    stage = groom_stage(tmp_path / "in.usda", strands=400, vertices=12, end=60)
    jobs = write_jobs(tmp_path / "jobs.toml", [{"input": "in.usda", "output": "out/a.usdc", "substeps": 8}])
    out = tmp_path / "out"
    p = subprocess.Popen(batch_command(jobs, "--workers", "1", "--checkpoint-frames", "2"), cwd=tmp_path,
                         stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, env=ENV)
    try:
        deadline = time.monotonic() + 120
        while not (out / ".a.usdc.dftl-checkpoint.npz").exists():
            assert p.poll() is None, p.communicate()
            assert time.monotonic() < deadline
            time.sleep(0.02)
        p.send_signal(signal.SIGTERM)
        _, err = p.communicate(timeout=30)
    finally:
        if p.poll() is None:
            p.kill()
    assert p.returncode == 143 and "dftl-warp: stopped by SIGTERM" in err and "Traceback" not in err, err
    assert not (out / "a.usdc").exists()
    assert ".a.usdc.dftl-checkpoint.npz" in hidden_files(out) and ".a.usdc.dftl-checkpoint.usdc" in hidden_files(out)
    rerun = subprocess.run(batch_command(jobs, "--workers", "1", "--checkpoint-frames", "2"), cwd=tmp_path,
                           capture_output=True, text=True, env=ENV, timeout=120)
    assert rerun.returncode == 0 and "resumed after frame" in rerun.stderr, rerun.stderr
    assert hidden_files(out) == [] and (out / "a.usdc").exists()
    del stage


# -- 5. authored normals --------------------------------------------------------------------------


def test_authored_normals_are_blocked_in_the_output_and_warned_about(tmp_path, capsys):
    from pxr import Gf, Sdf, Usd, UsdGeom, Vt

    stage = Usd.Stage.CreateNew(str(tmp_path / "in.usda"))
    stage.SetStartTimeCode(1)
    stage.SetEndTimeCode(3)
    curves = UsdGeom.BasisCurves.Define(stage, "/Hair")
    curves.CreatePointsAttr(Vt.Vec3fArray([Gf.Vec3f(0, 0, 0), Gf.Vec3f(1, 0, 0), Gf.Vec3f(2, 0, 0)]))
    curves.CreateCurveVertexCountsAttr([3])
    curves.CreateTypeAttr("linear")
    curves.CreateNormalsAttr(Vt.Vec3fArray([Gf.Vec3f(0, 1, 0)] * 3))
    UsdGeom.PrimvarsAPI(curves).CreatePrimvar("normals", Sdf.ValueTypeNames.Normal3fArray, UsdGeom.Tokens.vertex).Set(
        Vt.Vec3fArray([Gf.Vec3f(0, 0, 1)] * 3))
    stage.Save()
    out = tmp_path / "out.usda"
    assert cli.main(["simulate", str(tmp_path / "in.usda"), "-o", str(out), "--device", "cpu"]) == 0
    err = capsys.readouterr().err
    assert "normals and primvars:normals describe the authored shape" in err
    result = Usd.Stage.Open(str(out))
    prim = result.GetPrimAtPath("/Hair")
    assert prim.GetAttribute("normals").Get(3) is None and not prim.GetAttribute("normals").HasAuthoredValue()
    assert prim.GetAttribute("primvars:normals").Get(3) is None
    # the points moved: the blocked normals are not left behind at rest
    assert not np.allclose(np.array(prim.GetAttribute("points").Get(3)), [[0, 0, 0], [1, 0, 0], [2, 0, 0]])


def test_every_command_prints_its_help(capsys):
    # argparse formats help text with %: an option's help with a bare % once broke --help
    commands = next(a for a in cli.build_parser()._actions if a.dest == "command").choices
    assert {"simulate", "render", "batch", "study", "info", "import", "diff"} <= set(commands)
    for name in commands:
        with pytest.raises(SystemExit) as exc:
            cli.main([name, "--help"])
        assert exc.value.code == 0, name
        assert "usage" in capsys.readouterr().out
