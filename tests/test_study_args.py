"""``dftl-warp study`` with bad arguments (docs/accuracy.md): one line naming the option, exit 2,
no traceback, nothing written; flags that do nothing are said, not ignored silently."""

import json
from pathlib import Path

import pytest

from dftl_warp.cli import main

FRONT = Path(__file__).parents[1] / "docs" / "accuracy-h200" / "front.json"


def one_error(capsys, argv) -> str:
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "Traceback" not in err, err
    return err


@pytest.mark.parametrize("content", ["[1, 2]", '{"result": [], "meta": []}', '{"result": {}, "meta": {}}',
                                     '{"result": {"rows": [1]}, "meta": {}}', '{"result": {"rows": []}, "meta": {}}'])
def test_front_from_a_json_that_is_not_a_front_is_one_line_and_writes_nothing(tmp_path, capsys, content):
    bad = tmp_path / "bad.json"
    bad.write_text(content)
    out = tmp_path / "out"
    err = one_error(capsys, ["study", "--front-from", str(bad), "--out", str(out), "--quiet"])
    assert err.startswith(f"dftl-warp: error: --front-from {bad}: not a front.json"), err
    assert not out.exists()


def test_front_from_says_which_flags_do_nothing(tmp_path, capsys):
    err = one_error(capsys, ["study", "--front-from", str(FRONT), "--out", str(tmp_path / "a"),
                             "--docs", str(tmp_path / "d")])
    assert "--docs" in err and not (tmp_path / "a").exists()
    assert main(["study", "--front-from", str(FRONT), "--out", str(tmp_path / "b"), "--fast", "--strands", "5",
                 "--device", "cpu", "--quiet"]) == 0
    err = capsys.readouterr().err
    assert len(err.splitlines()) == 1 and "--fast" in err and "--strands" in err and "--device" in err, err
    assert "--front-from" in err
    redrawn = json.loads((tmp_path / "b" / "front.json").read_text())
    assert redrawn["presets"] == json.loads(FRONT.read_text())["presets"]


@pytest.mark.parametrize("flags, expected", [
    (["--strands", "0"], "--strands 0: must be at least 1"),
    (["--strands", "-3"], "--strands -3: must be at least 1"),
    (["--strands", "1000000000000"], "--strands 1000000000000: must be at most 10,000,000"),
    (["--particles", "1"], "--particles 1: must be at least 2"),
    (["--particles", "100000000"], "--particles 100000000: must be at most 1,024"),
    (["--frames", "0"], "--frames 0: must be at least 1"),
    (["--frames", "100000000"], "--frames 100000000: must be at most 10,000"),
    (["--reference-substeps", "1"], "--reference-substeps 1: must be at least 2"),
    (["--reference-substeps", "99999999"], "--reference-substeps 99999999: must be at most 16,384"),
    (["--strands", "10000000", "--particles", "1000"], "--strands 10000000 x --particles 1000 = 10,000,000,000 "
                                                         "particles: at most 2,147,483,647"),
])
def test_front_sizes_out_of_range_are_one_line_before_any_work(tmp_path, capsys, flags, expected):
    # before: zero and negative sizes were refused, but 10^12 strands or 10^8 particles per strand
    # ended in numpy's MemoryError traceback, and 10^8 frames ran until killed
    out = tmp_path / "out"
    err = one_error(capsys, ["study", "--front", "--fast", "--device", "cpu", "--out", str(out), "--quiet", *flags])
    assert err == f"dftl-warp: error: {expected}", err
    assert not out.exists()


@pytest.mark.parametrize("out, why", [("/proc/dftl-x", "cannot create a file in folder /proc"),
                                      ("afile/sub", "is not a folder")])
def test_an_out_folder_that_cannot_be_written_is_named_before_any_work(tmp_path, capsys, monkeypatch, out, why):
    # before: the redraw blamed the json ("--front-from F: not a front.json ([Errno 2] ... '/proc/x')"), and a
    # full study found it only after running
    monkeypatch.chdir(tmp_path)
    (tmp_path / "afile").write_text("")
    err = one_error(capsys, ["study", "--front-from", str(FRONT), "--out", out, "--quiet"])
    assert err.startswith(f"dftl-warp: error: --out {out}: ") and why in err, err
    import dftl_warp.study.sweeps as sweeps

    monkeypatch.setattr(sweeps, "run_study", lambda *a, **k: pytest.fail("the study ran before --out was checked"))
    err = one_error(capsys, ["study", "--fast", "--device", "cpu", "--out", out, "--quiet"])
    assert err.startswith(f"dftl-warp: error: --out {out}: ") and why in err, err


def test_redrawing_the_front_prints_no_matplotlib_warning(tmp_path, capsys, monkeypatch):
    # matplotlib warns (two lines of Python's warning format) when placing the legend took over 1 s,
    # as on a loaded machine: a clock that jumps 2 s a reading makes every placement that slow
    import itertools
    import time as real_time
    import types

    import matplotlib.legend

    ticks = itertools.count(step=2.0)
    monkeypatch.setattr(matplotlib.legend, "time", types.SimpleNamespace(perf_counter=lambda: next(ticks),
                                                                         **{k: getattr(real_time, k) for k in
                                                                            ("time", "sleep", "monotonic")}))
    import warnings

    with warnings.catch_warnings(record=True) as seen:   # what Python would print on stderr
        warnings.simplefilter("always")
        assert main(["study", "--front-from", str(FRONT), "--out", str(tmp_path / "o"), "--quiet"]) == 0
    assert [str(w.message) for w in seen] == [] and capsys.readouterr().err == ""
