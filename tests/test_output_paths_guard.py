"""simulate's output guards through the command line: an output that is a layer the input uses is
refused (one line naming both files, exit 2, nothing written); an output folder that takes no files
is named as the output, not its lock file; a failed run leaves no folder it created; frames outside
the stage's animated time range run with one warning naming the file and both ranges; ``make demo``'s
commands run twice overwrite their own outputs."""

from __future__ import annotations

import errno
import hashlib
import os
import tempfile
from pathlib import Path

import pytest
from pxr import Sdf
from usd_stages import add_curves, animated_xform, chain, new_stage

from dftl_warp import cli
from dftl_warp.errors import UserError


def run_cli(capsys, *argv, quiet=True):
    code = cli.main(["simulate", *map(str, argv), *(["--quiet"] if quiet else [])])
    out, err = capsys.readouterr()
    return code, out, err


def tree(folder) -> dict[str, str]:
    """Every file under ``folder`` (hidden ones too) with its content's digest."""
    return {str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest() if p.is_file() else "dir"
            for p in sorted(Path(folder).rglob("*"))}


def refused(capsys, folder, argv, *expected) -> str:
    """Exit 2, one stderr line holding every expected piece, no traceback, nothing under
    ``folder`` written, changed or added."""
    before = tree(folder)
    code, out, err = run_cli(capsys, *argv)
    assert code == 2, err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("dftl-warp: error: "), err
    assert "Traceback" not in err
    for piece in expected:
        assert piece in lines[0], (piece, lines[0])
    assert tree(folder) == before
    return lines[0]


def hair_layer(path: Path, **kw) -> Path:
    stage = new_stage(path, **kw)
    add_curves(stage, "/World/Hair", chain(4, spacing=0.1), [4])
    stage.Save()
    return path


def wrapper(path: Path, *, sublayers=(), reference=None, payload=None) -> Path:
    """A stage that sublayers ``sublayers`` and references / payloads a layer under /World/Ref."""
    layer = Sdf.Layer.CreateNew(str(path))
    layer.subLayerPaths[:] = list(sublayers)
    layer.startTimeCode, layer.endTimeCode = 1, 3
    if reference or payload:
        spec = Sdf.PrimSpec(layer, "Ref", Sdf.SpecifierDef)
        if reference:
            spec.referenceList.Prepend(Sdf.Reference(reference, "/World"))
        if payload:
            spec.payloadList.Prepend(Sdf.Payload(payload, "/World"))
    layer.Save()
    return path


# -- 1. an output that is a layer the input uses ---------------------------------------------------


def test_output_onto_a_sublayer_of_the_input_is_refused(tmp_path, capsys):
    dep = hair_layer(tmp_path / "dep.usda")
    top = wrapper(tmp_path / "top.usda", sublayers=["./dep.usda"])
    refused(capsys, tmp_path, [top, "-o", dep], f"{dep}: the output would overwrite {dep.resolve()}",
            f"which the input {top} uses")


@pytest.mark.parametrize("arc", ["reference", "payload"])
def test_output_onto_a_referenced_or_payload_layer_is_refused(tmp_path, capsys, arc):
    (tmp_path / "assets").mkdir()
    dep = hair_layer(tmp_path / "assets" / "groom.usdc")
    top = wrapper(tmp_path / "shot.usda", **{arc: "./assets/groom.usdc"})
    refused(capsys, tmp_path, [top, "-o", dep], f"{dep}: the output would overwrite", "groom.usdc",
            f"which the input {top} uses")


def test_a_nested_dependency_reached_through_a_symlink_is_refused(tmp_path, capsys):
    (tmp_path / "deep").mkdir()
    dep = hair_layer(tmp_path / "deep" / "hair.usda")
    wrapper(tmp_path / "mid.usda", sublayers=["./deep/hair.usda"])
    top = wrapper(tmp_path / "top.usda", sublayers=["./mid.usda"])
    (tmp_path / "alias.usda").symlink_to(dep)
    refused(capsys, tmp_path, [top, "-o", tmp_path / "alias.usda"], "alias.usda: the output would overwrite",
            str(dep.resolve()), f"which the input {top} uses")


def test_output_onto_a_missing_sublayer_is_refused(tmp_path, capsys):
    hair_layer(tmp_path / "hair.usda")
    top = wrapper(tmp_path / "top.usda", sublayers=["./hair.usda", "./later.usda"])
    refused(capsys, tmp_path, [top, "-o", tmp_path / "later.usda"],
            f"{tmp_path / 'later.usda'}: the input {top} uses this path as a layer (missing now)")
    assert not (tmp_path / "later.usda").exists()


def test_an_unrelated_existing_output_is_still_overwritten(tmp_path, capsys):
    hair_layer(tmp_path / "dep.usda")
    top = wrapper(tmp_path / "top.usda", sublayers=["./dep.usda"])
    out = tmp_path / "out.usda"
    out.write_text("#usda 1.0\n")
    code, _, err = run_cli(capsys, top, "-o", out)
    assert code == 0, err
    assert "@./top.usda@" in out.read_text()
    assert Sdf.Layer.FindOrOpen(str(tmp_path / "dep.usda")).GetPrimAtPath("/World/Hair")


# -- 2. output folders -----------------------------------------------------------------------------


def test_a_folder_that_takes_no_files_names_the_output(tmp_path, capsys, monkeypatch):
    # root writes into read-only folders and os.access says yes on read-only file systems
    # (/sys): the folder is tried with a real file before any work
    f = hair_layer(tmp_path / "in.usda")
    (tmp_path / "ro").mkdir()
    real = tempfile.mkstemp

    def mkstemp(*a, dir=None, **k):
        if Path(dir) == tmp_path / "ro":
            raise PermissionError(errno.EACCES, "Permission denied")
        return real(*a, dir=dir, **k)

    monkeypatch.setattr(tempfile, "mkstemp", mkstemp)
    out = tmp_path / "ro" / "x.usda"
    line = refused(capsys, tmp_path, [f, "-o", out],
                   f"{out}: cannot write: cannot create a file in folder {tmp_path / 'ro'} (permission denied)")
    assert "dftl-lock" not in line


def test_a_lock_file_that_cannot_be_created_names_the_output(tmp_path, monkeypatch):
    from dftl_warp.output.lock import lock_path, output_lock

    out = tmp_path / "x.usdc"
    real = os.open

    def fail(path, *a, **k):
        if Path(path) == lock_path(out):
            raise PermissionError(errno.EACCES, "Permission denied")
        return real(path, *a, **k)

    monkeypatch.setattr(os, "open", fail)
    with pytest.raises(UserError) as info, output_lock(lock_path(out)):
        pass
    assert str(info.value) == f"{out}: cannot write: cannot create a file in folder {tmp_path} (permission denied)"


def test_a_failed_run_leaves_no_folder_it_created(tmp_path, capsys):
    f = hair_layer(tmp_path / "in.usda")
    before = tree(tmp_path)
    # refused before any work: bad input
    code, _, err = run_cli(capsys, tmp_path / "nope.usda", "-o", tmp_path / "new" / "a" / "out.usdc")
    assert code == 2 and "nope.usda: no such file" in err
    # refused while writing (inside the output's place): --clips into a .usda layer
    code, _, err = run_cli(capsys, f, "-o", tmp_path / "new" / "a" / "out.usda", "--clips", "2")
    lines = err.strip().splitlines()
    assert code == 2 and len(lines) == 1 and "--clips writes a .usdc or .usd output layer" in lines[0], err
    assert tree(tmp_path) == before
    # a folder that was there before stays
    (tmp_path / "kept").mkdir()
    code, _, err = run_cli(capsys, f, "-o", tmp_path / "kept" / "deeper" / "out.usda", "--clips", "2")
    assert code == 2 and (tmp_path / "kept").is_dir() and not (tmp_path / "kept" / "deeper").exists()


def test_a_missing_folder_is_still_created_for_a_run_that_succeeds(tmp_path, capsys):
    f = hair_layer(tmp_path / "in.usda")
    out = tmp_path / "x" / "y" / "out.usdc"
    code, _, err = run_cli(capsys, f, "-o", out, "--end", "2")
    assert code == 0 and out.is_file(), err
    assert sorted(p.name for p in out.parent.iterdir()) == ["out.usdc"]


# -- 3. frames outside the stage's time range ------------------------------------------------------


def animated_stage(path: Path, **kw) -> Path:
    stage = new_stage(path, **kw)   # 1..10
    animated_xform(stage, "/World/Head", translate={1: (0, 0, 0), 10: (0.5, 0, 0)})
    add_curves(stage, "/World/Head/Hair", chain(4, spacing=0.05), [4])
    stage.Save()
    return path


def warnings(err: str) -> list[str]:
    return [line for line in err.splitlines() if line.startswith("dftl-warp: warning:")]


@pytest.mark.parametrize("start, end, where", [(20, 25, "outside"), (5, 14, "partly outside"),
                                               (-2, 3, "partly outside")])
def test_frames_outside_the_animated_range_warn_once_and_run(tmp_path, capsys, start, end, where):
    f = animated_stage(tmp_path / "anim.usda")
    out = tmp_path / "o.usda"
    code, _, err = run_cli(capsys, f, "-o", out, "--start", start, "--end", end, quiet=False)
    assert code == 0 and out.is_file(), err
    hits = [w for w in warnings(err) if "time range" in w]
    assert hits == [f"dftl-warp: warning: {f}: frames {start}..{end} lie {where} the stage's time range 1..10 "
                    f"(startTimeCode..endTimeCode): there the animation holds its first or last pose"], err


def test_frames_inside_the_range_do_not_warn(tmp_path, capsys):
    f = animated_stage(tmp_path / "anim.usda")
    code, _, err = run_cli(capsys, f, "-o", tmp_path / "o.usda", "--start", 2, "--end", 9, quiet=False)
    assert code == 0 and not [w for w in warnings(err) if "time range" in w], err


def test_a_static_stage_or_one_without_a_range_does_not_warn(tmp_path, capsys):
    static = hair_layer(tmp_path / "static.usda")   # 1..10, nothing animated: the hair just falls longer
    code, _, err = run_cli(capsys, static, "-o", tmp_path / "a.usda", "--start", 1, "--end", 30, quiet=False)
    assert code == 0 and not [w for w in warnings(err) if "time range" in w], err
    bare = animated_stage(tmp_path / "bare.usda", start=None, end=None)
    code, _, err = run_cli(capsys, bare, "-o", tmp_path / "b.usda", "--start", 20, "--end", 22, quiet=False)
    assert code == 0 and not [w for w in warnings(err) if "time range" in w], err


def test_quiet_keeps_the_range_warning_and_nothing_else(tmp_path, capsys):
    """-q silences progress and notes, never a warning (as render -q and batch --quiet): the range
    warning is the one line on stderr (it was dropped with the progress)."""
    f = animated_stage(tmp_path / "anim.usda")
    code, _, err = run_cli(capsys, f, "-o", tmp_path / "o.usda", "--start", 20, "--end", 21)
    assert code == 0 and err.splitlines() == [
        f"dftl-warp: warning: {f}: frames 20..21 lie outside the stage's time range 1..10 "
        f"(startTimeCode..endTimeCode): there the animation holds its first or last pose"], err


def test_the_api_summary_carries_the_range_warning(tmp_path):
    from dftl_warp.simulation.simulate import simulate_usd

    f = animated_stage(tmp_path / "anim.usda")
    s = simulate_usd(str(f), str(tmp_path / "o.usda"), start=11, end=12, device="cpu")
    assert [w for w in s.warnings if "lie outside the stage's time range 1..10" in w]


def test_the_demo_commands_run_twice_overwrite_their_own_outputs(tmp_path, capsys):
    """``make demo`` twice in a row: the second simulate and render overwrite out/demo.usdc and
    out/demo.png and leave nothing else behind (a chain stands in for the default groom)."""
    import shutil

    src = tmp_path / "chain.usda"
    shutil.copy(Path(__file__).resolve().parents[1] / "scenes" / "chain.usda", src)
    out = tmp_path / "out"
    out.mkdir()
    pictures = []
    for _ in range(2):
        assert cli.main(["simulate", str(src), "-o", str(out / "demo.usdc"), "--end", "6", "--quiet"]) == 0
        assert cli.main(["render", str(out / "demo.usdc"), "--frame", "5", "--resolution", "32x24", "--spp", "2",
                         "-o", str(out / "demo.png"), "-q"]) == 0
        assert sorted(p.name for p in out.iterdir()) == ["demo.png", "demo.usdc"]
        pictures.append((out / "demo.png").read_bytes())
    assert capsys.readouterr().err == ""
    assert pictures[0] == pictures[1]
