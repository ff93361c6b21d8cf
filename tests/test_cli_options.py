"""Command-line options that were ignored or misreported: --guides in the guides' own words, flags
that do nothing here warn once, --quality with --tolerance says what the tolerance overrode (and the
provenance does not claim the preset), the preroll line with --guides and --tolerance, a bad
$DFTL_WARP_DEVICE named as the variable, study's elapsed time, empty paths and gates, --guides-output
with no guides, and --substeps / --preroll past their limits."""

import json

import numpy as np
import pytest
from pxr import Sdf
from usd_stages import add_curves, new_stage

from dftl_warp import cli

N = 8


def hair(path):
    stage = new_stage(path, start=1, end=3)
    pts = []
    for a in np.linspace(0, 2 * np.pi, 12, endpoint=False):
        for i in range(N):
            pts.append([0.1 * np.cos(a) + 0.02 * i, -0.02 * i, 0.1 * np.sin(a)])
    add_curves(stage, "/World/Hair", np.array(pts), [N] * 12)
    stage.Save()
    return path


def simulate(capsys, *argv, quiet=True):
    code = cli.main(["simulate", *map(str, argv), "--device", "cpu", "--end", "2", *(["--quiet"] if quiet else [])])
    out = capsys.readouterr()
    return code, out.err


@pytest.mark.parametrize("bad", ["-3", "abc", "nan", "", "1e-9"])
def test_bad_guides_get_the_guides_message(tmp_path, capsys, bad):
    src, out = hair(tmp_path / "h.usda"), tmp_path / "o.usdc"
    code, err = simulate(capsys, src, "-o", out, "--guides", bad)
    assert code == 2 and len(err.strip().splitlines()) == 1, err
    assert "expected a number of guides, a fraction or a percentage" in err and "must be a string" not in err
    assert not out.exists()


def test_guides_api_message():
    from dftl_warp.options import OptionError, check_api

    with pytest.raises(OptionError, match="guides must be a number of guides, a fraction or a percentage"):
        check_api("guides", "-3")


def test_guide_method_without_guides_warns(tmp_path, capsys):
    src = hair(tmp_path / "h.usda")
    code, err = simulate(capsys, src, "-o", tmp_path / "o.usdc", "--guide-method", "fps", quiet=False)
    assert code == 0
    assert err.count("--guide-method fps does nothing without --guides") == 1


def test_quality_with_tolerance_warns_and_provenance_says_so(tmp_path, capsys):
    src, out = hair(tmp_path / "h.usda"), tmp_path / "o.usda"
    code, err = simulate(capsys, src, "-o", out, "--quality", "draft", "--tolerance", "0.1", quiet=False)
    assert code == 0
    assert err.count("--quality draft with --tolerance 0.1: the tolerance chooses the solver and the substeps") == 1
    assert "16 substeps per frame" not in err   # the preset's line would claim what did not run
    layer = Sdf.Layer.FindOrOpen(str(out))
    record = layer.customLayerData["dftl_warp_provenance"]
    text = json.dumps(dict(record), default=str)
    assert "draft (solver and substeps chosen by tolerance)" in text


@pytest.mark.parametrize("extra", [[], ["--guides", "3"], ["--tolerance", "0.1"]])
def test_preroll_line_is_printed_with_guides_and_tolerance(tmp_path, capsys, extra):
    src = hair(tmp_path / "h.usda")
    code, err = simulate(capsys, src, "-o", tmp_path / "o.usdc", "--preroll", "0.1", *extra, quiet=False)
    assert code == 0
    prefixes = ("dftl-warp: preroll: ", "dftl-warp: warning: preroll: ")   # settled, or not
    assert sum(line.startswith(prefixes) for line in err.splitlines()) == 1, err


def test_bad_device_variable_is_named(tmp_path, capsys, monkeypatch):
    monkeypatch.setenv("DFTL_WARP_DEVICE", "cuda:7")
    src, out = hair(tmp_path / "h.usda"), tmp_path / "o.usdc"
    code = cli.main(["simulate", str(src), "-o", str(out), "--end", "2", "--quiet"])
    err = capsys.readouterr().err.strip()
    assert code == 2 and len(err.splitlines()) == 1, err
    assert "$DFTL_WARP_DEVICE=cuda:7" in err and "--device" not in err
    assert not out.exists()


def test_study_warns_front_flags_and_reports_elapsed_time(tmp_path, capsys, monkeypatch):
    import time

    from dftl_warp.study import report, sweeps

    def slow_study(cfg, log):
        time.sleep(1.3)
        return {"seconds": 0.0}

    monkeypatch.setattr(sweeps, "run_study", slow_study)
    monkeypatch.setattr(report, "write_results", lambda results, meta, out, docs: [])
    code = cli.main(["study", "--fast", "--device", "cpu", "--out", str(tmp_path / "s"), "--strands", "10"])
    out = capsys.readouterr()
    assert code == 0
    assert out.err.count("--strands does nothing without --front") == 1
    assert "study: " not in out.out   # progress goes to stderr, prefixed as every command's
    line = [x for x in out.err.splitlines() if x.startswith("dftl-warp: study: ")][-1].removeprefix("dftl-warp: ")
    assert float(line.split()[1]) >= 1.3, line


def test_solver_options_no_prim_uses_are_warned_about(tmp_path, capsys):
    """--iterations sets the pbd solver's iterations and --arithmetic the elastic solver's: on a
    scene where no prim runs that solver they did nothing, without a word."""
    import shutil
    from pathlib import Path

    from dftl_warp import cli

    src = tmp_path / "chain.usda"
    shutil.copy(Path(__file__).resolve().parents[1] / "scenes" / "chain.usda", src)
    assert cli.main(["simulate", str(src), "-o", str(tmp_path / "a.usdc"), "--end", "2",
                     "--iterations", "5", "--arithmetic", "float32"]) == 0
    err = capsys.readouterr().err
    assert "--iterations 5 does nothing here: no prim runs the pbd solver" in err, err
    assert "--arithmetic float32 does nothing here: no prim runs the elastic solver" in err, err
    assert cli.main(["simulate", str(src), "-o", str(tmp_path / "b.usdc"), "--end", "2",
                     "--solver", "pbd", "--iterations", "5"]) == 0
    assert "does nothing" not in capsys.readouterr().err


def one_line(capsys, *fragments):
    err = capsys.readouterr().err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in err, err
    for f in fragments:
        assert f in lines[0], err
    return lines[0]


@pytest.mark.parametrize("argv, message", [
    (["-o", ""], "argument -o/--output: empty path: give the layer to write, such as out/groom.usdc"),
    (["-o", " "], "argument -o/--output: empty path"),
    (["-o", "o.usdc", "--check", ""], "--check '': no gates: give METRIC<LIMIT gates such as "
                                      "'stretch<1e-3,penetration<0.05' (metrics: stretch, penetration"),
    (["-o", "o.usdc", "--check", "  "], "--check '  ': no gates"),
])
def test_empty_output_and_empty_gates_are_one_clear_line(tmp_path, capsys, argv, message):
    """-o '' said ".: output must end in .usdc"; --check '' said "check must be a string"."""
    src = hair(tmp_path / "h.usda")
    with pytest.raises(SystemExit) as e:
        cli.main(["simulate", str(src), *argv])
    assert e.value.code == 2
    one_line(capsys, message)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["h.usda"]
    with pytest.raises(SystemExit):
        cli.main(["simulate", "", "-o", str(tmp_path / "o.usdc")])
    one_line(capsys, "argument INPUT: empty path: give the USD stage to simulate")
    with pytest.raises(SystemExit):
        cli.main(["import", str(tmp_path / "h.hair"), "-o", ""])
    one_line(capsys, "argument -o/--output: empty path: give the stage to write, such as groom.usda")


def test_empty_output_and_empty_gates_through_the_api(tmp_path):
    from dftl_warp.errors import UserError
    from dftl_warp.importers.convert import import_groom
    from dftl_warp.simulation.simulate import simulate_usd

    src = hair(tmp_path / "h.usda")
    with pytest.raises(UserError, match=r"^output '': empty path: give the file to write \(\.usdc"):
        simulate_usd(src, "")
    with pytest.raises(UserError, match=r"^check '': no gates: give METRIC<LIMIT gates"):
        simulate_usd(src, tmp_path / "o.usdc", check="")
    with pytest.raises(UserError, match=r"^check 3: expected a string of METRIC<LIMIT gates"):
        simulate_usd(src, tmp_path / "o.usdc", check=3)
    with pytest.raises(UserError, match=r"^output '': empty path: give the stage to write"):
        import_groom(tmp_path / "h.hair", "")
    from dftl_warp.batch.jobs import _simulate_options

    with pytest.raises(ValueError, match=r"check '': no gates"):
        _simulate_options()["check"]("", "check")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["h.usda"]


def test_guides_output_without_guides_is_refused_or_warned(tmp_path, capsys):
    """--guides-output was dropped without a word where no prim is guide-driven: binding (an output
    without the binding asked for) is refused before anything runs, curves (what is written anyway)
    says it does nothing. A stage with rel dftl:guides takes it (tests/test_guides_cli.py)."""
    src, out = hair(tmp_path / "h.usda"), tmp_path / "o.usdc"
    code, err = simulate(capsys, src, "-o", out, "--guides-output", "binding")
    assert code == 2 and not out.exists()
    assert err.strip().splitlines() == [
        f"dftl-warp: error: {src}: --guides-output binding: no prim here is driven by guides (give --guides "
        "N|FRACTION to pick them from each prim, or author rel dftl:guides on the render prims)"]
    code, err = simulate(capsys, src, "-o", out, "--guides-output", "curves", quiet=False)
    assert code == 0 and out.exists()
    assert err.count("dftl-warp: warning: --guides-output curves does nothing: no prim here is driven by guides") == 1
    code, err = simulate(capsys, src, "-o", tmp_path / "g.usdc", "--guides", "3", "--guides-output", "binding",
                         quiet=False)
    assert code == 0 and "does nothing" not in err
    from dftl_warp.errors import UserError
    from dftl_warp.simulation.simulate import simulate_usd

    with pytest.raises(UserError, match="guides_output binding: no prim here is driven by guides \\(give guides N"):
        simulate_usd(src, tmp_path / "api.usdc", end=2, guides_output="binding")


@pytest.mark.parametrize("argv, message", [
    (["--substeps", "1000000000"], "argument --substeps: must be at most 16384, got 1000000000"),
    (["--substeps", "99999999999999999999"], "argument --substeps: must be at most 16384"),
    (["--preroll", "1e9"], "argument --preroll: must be at most 60, got 1e9"),
    (["--iterations", "100000"], "argument --iterations: must be at most 1024, got 100000"),
])
def test_absurd_substeps_and_preroll_are_refused_with_the_limit(tmp_path, capsys, argv, message):
    """--substeps 10**9 or --preroll 1e9 ran for days (the big integer was "not an integer")."""
    src, out = hair(tmp_path / "h.usda"), tmp_path / "o.usdc"
    with pytest.raises(SystemExit) as e:
        simulate(capsys, src, "-o", out, *argv)
    assert e.value.code == 2 and not out.exists()
    one_line(capsys, message)


def test_every_quiet_command_takes_q(tmp_path, capsys):
    """-q is --quiet wherever --quiet is (import and render took -q; simulate, batch and study
    refused it as an unrecognized argument), and simulate -q prints what --quiet does: no
    progress, only the summary line."""
    import argparse

    sub = next(a for a in cli.build_parser()._actions if isinstance(a, argparse._SubParsersAction))
    quiet = {name: p for name, p in sub.choices.items() if "--quiet" in p._option_string_actions}
    assert {"simulate", "batch", "study", "import", "render"} <= set(quiet)
    for name, p in quiet.items():
        assert p._option_string_actions.get("-q") is p._option_string_actions["--quiet"], name
    path = hair(tmp_path / "in.usda")
    errs = []
    for flag in ("-q", "--quiet"):
        assert cli.main(["simulate", str(path), "-o", str(tmp_path / f"o{flag}.usdc"), "--device", "cpu", "--end", "2",
                         flag]) == 0
        errs.append(capsys.readouterr().err)
    assert errs[0] == errs[1] == "", errs
