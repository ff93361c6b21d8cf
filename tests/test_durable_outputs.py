"""Finished outputs survive a power loss: every file is flushed to the disk (fsync) before it is
renamed onto its final name, and its folder is flushed after the rename (dftl_warp/durable.py).

Before, ``simulate`` renamed its partial file into place without an fsync, so a power loss right
after "done" could leave an empty or truncated output under the final name. The tests record the
system calls (os.fsync, os.replace) a command makes and check their order on the real files.
"""

from __future__ import annotations

import os
from pathlib import Path

import pytest
from usd_stages import add_curves, chain, new_stage

from dftl_warp import cli, durable


@pytest.fixture
def calls(monkeypatch):
    """The (what, path) of every os.fsync and os.replace, in order; an fsync is named by the real
    path of its descriptor."""
    seen = []
    fsync, replace = os.fsync, os.replace

    def record_fsync(fd):
        seen.append(("fsync", os.path.realpath(os.readlink(f"/proc/self/fd/{fd}"))))
        return fsync(fd)

    def record_replace(src, dst, *a, **k):
        seen.append(("replace", os.path.realpath(src), os.path.realpath(dst)))
        return replace(src, dst, *a, **k)

    monkeypatch.setattr(os, "fsync", record_fsync)
    monkeypatch.setattr(os, "replace", record_replace)
    return seen


pytestmark = pytest.mark.skipif(not os.path.isdir("/proc/self/fd"), reason="names descriptors through /proc")


def hair(path: Path) -> Path:
    stage = new_stage(path)
    add_curves(stage, "/World/Hair", chain(4, spacing=0.1), [4])
    stage.Save()
    return path


def check_durable_rename(calls, final: Path):
    """The rename onto ``final``: its source was fsync'd before it, and ``final``'s folder after it."""
    final = os.path.realpath(final)
    renames = [i for i, c in enumerate(calls) if c[0] == "replace" and c[2] == final]
    assert len(renames) == 1, calls
    i = renames[0]
    source = calls[i][1]
    assert ("fsync", source) in calls[:i], f"{source} renamed onto {final} without an fsync: {calls}"
    assert ("fsync", os.path.dirname(final)) in calls[i + 1:], f"folder of {final} not fsync'd: {calls}"


@pytest.mark.parametrize("suffix", [".usdc", ".usda"])
def test_simulate_flushes_its_output_before_and_after_the_rename(tmp_path, calls, suffix):
    src = hair(tmp_path / "in.usda")
    out = tmp_path / "out" / f"shot{suffix}"
    assert cli.main(["simulate", str(src), "-o", str(out), "--end", "2", "--device", "cpu", "-q"]) == 0
    assert out.is_file()
    check_durable_rename(calls, out)


def test_value_clips_are_on_the_disk_before_their_folder_and_the_output_are_renamed(tmp_path, calls):
    src = hair(tmp_path / "in.usda")
    out = tmp_path / "shot.usdc"
    assert cli.main(["simulate", str(src), "-o", str(out), "--end", "4", "--clips", "2", "--device", "cpu", "-q"]) == 0
    folder = os.path.realpath(tmp_path / "shot_clips")
    clips = sorted(os.path.realpath(p) for p in Path(folder).iterdir())
    assert len(clips) >= 3, clips   # topology + 2 chunks
    moved = [i for i, c in enumerate(calls) if c[0] == "replace" and c[2] == folder]
    assert len(moved) == 1, calls
    i = moved[0]
    partial = calls[i][1]
    for clip in clips:   # each file as it was named in the partial folder, fsync'd before the move
        assert ("fsync", os.path.join(partial, os.path.basename(clip))) in calls[:i], (clip, calls)
    assert ("fsync", partial) in calls[:i]
    check_durable_rename(calls, out)
    assert i < max(j for j, c in enumerate(calls) if c[0] == "replace" and c[2] == os.path.realpath(out))


def test_render_flushes_its_image(tmp_path, calls):
    src = hair(tmp_path / "in.usda")
    out = tmp_path / "frame.png"
    assert cli.main(["render", str(src), "-o", str(out), "--resolution", "16x12", "--spp", "1", "--device", "cpu",
                     "-q"]) == 0
    check_durable_rename(calls, out)


def test_import_flushes_the_stage_it_writes(tmp_path, calls):
    ply = tmp_path / "g.ply"
    ply.write_text("\n".join(["ply", "format ascii 1.0", "element vertex 6", "property float x", "property float y",
                              "property float z", "element strand 2", "property int vertex_count", "end_header",
                              "0 0 0", "0 -1 0", "0 -2 0", "1 0 0", "1 -1 0", "1 -2 0", "3", "3"]) + "\n")
    out = tmp_path / "groom.usda"
    assert cli.main(["import", str(ply), "-o", str(out), "-q"]) == 0
    check_durable_rename(calls, out)


def test_write_file_leaves_the_old_file_when_writing_fails(tmp_path):
    path = tmp_path / "report.md"
    path.write_text("old")

    def fail(tmp):
        Path(tmp).write_text("half")
        raise OSError(28, "No space left on device")

    with pytest.raises(OSError):
        durable.write_file(path, fail)
    assert path.read_text() == "old"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["report.md"]


def test_write_text_is_durable_and_gets_the_usual_permissions(tmp_path, calls):
    path = tmp_path / "accuracy.md"
    durable.write_text(path, "# report\n")
    assert path.read_text() == "# report\n"
    check_durable_rename(calls, path)
    umask = os.umask(0)
    os.umask(umask)
    assert path.stat().st_mode & 0o777 == 0o666 & ~umask
