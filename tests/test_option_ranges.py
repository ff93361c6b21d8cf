"""Numeric options out of range or ignored, checked the same way in every command: one line on
stderr naming the flag, exit 2, no traceback, nothing written; a flag that does nothing warns.

Before: ``render --step 0`` (or any --step) without --start/--end was ignored without a word;
``import --segments 100000000`` ran until killed; ``study --front`` with sizes whose groom does not
fit in memory ended in numpy's MemoryError traceback.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from render_util import add_curves, new_stage

from dftl_warp import cli

PLY = ["ply", "format ascii 1.0", "element vertex 6", "property float x", "property float y", "property float z",
       "element strand 2", "property int vertex_count", "end_header",
       "0 0 0", "0 -1 0", "0 -2 0", "1 0 0", "1 -1 0", "1 -2 0", "3", "3"]


def one_line(capsys, prefix: str) -> str:
    err = capsys.readouterr().err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(prefix), err
    assert "Traceback" not in err
    return lines[0]


@pytest.fixture
def static_groom(tmp_path):
    path = tmp_path / "static.usda"
    stage = new_stage(path)
    add_curves(stage, "/hair", [np.array([[0.0, 0, 0], [0.0, 0.5, 0.1], [0.1, 1.0, 0]])], widths=[0.03])
    stage.Save()
    return path


@pytest.mark.parametrize("step", ["0", "-1"])
def test_render_refuses_a_step_that_is_not_positive_with_or_without_a_range(static_groom, tmp_path, capsys, step):
    out = tmp_path / "out.png"
    assert cli.main(["render", str(static_groom), f"--step={step}", "-o", str(out), "-q"]) == 2
    assert one_line(capsys, "dftl-warp: error: ") == f"dftl-warp: error: --step {step}: must be positive"
    assert not out.exists()


def test_render_warns_that_a_step_without_a_range_does_nothing(static_groom, tmp_path, capsys):
    out = tmp_path / "out.png"
    assert cli.main(["render", str(static_groom), "--frame", "1", "--step", "2", "-o", str(out), "--resolution", "8x6",
                     "--spp", "1", "--device", "cpu", "-q"]) == 0
    line = one_line(capsys, "dftl-warp: warning: ")
    assert line == "dftl-warp: warning: --step 2 applies only to a --start/--end range: ignored"
    assert out.is_file()


def test_render_of_a_range_with_the_default_step_names_it_in_messages(static_groom, tmp_path, capsys):
    pattern = tmp_path / "f.####.png"
    assert cli.main(["render", str(static_groom), "--start", "1.5", "--end", "2.5", "-o", str(pattern), "-q"]) == 2
    assert "frame 1.5 (--step 1) is not a whole number" in one_line(capsys, "dftl-warp: error: ")


@pytest.mark.parametrize("segments, message", [("100000000", "expected at most 10000"),
                                               ("0", "expected an integer >= 1")])
def test_import_segments_out_of_range_is_one_line_before_reading(tmp_path, capsys, segments, message):
    src = tmp_path / "g.ply"
    src.write_text("\n".join(PLY) + "\n")
    out = tmp_path / "g.usda"
    assert cli.main(["import", str(src), "-o", str(out), "--segments", segments, "-q"]) == 2
    line = one_line(capsys, "dftl-warp: error: ")
    assert line == f"dftl-warp: error: segments / --segments = {segments}: {message}"
    assert not out.exists()


def test_study_front_that_does_not_fit_in_memory_is_one_line(tmp_path, capsys, monkeypatch):
    from dftl_warp.study import front

    def no_memory(**kw):   # what numpy raises for a groom of more particles than the machine holds
        raise MemoryError("Unable to allocate 143. GiB for an array with shape (64, 100000000, 3)")

    monkeypatch.setattr(front, "measure_front", no_memory)
    out = tmp_path / "out"
    assert cli.main(["study", "--front", "--device", "cpu", "--strands", "1000000", "--particles", "1000",
                     "--out", str(out), "--quiet"]) == 2
    line = one_line(capsys, "dftl-warp: error: ")
    assert line.startswith("dftl-warp: error: --strands 1000000 x --particles 1000: the front's groom does not fit")
    assert not Path(out).exists()
