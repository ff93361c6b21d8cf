"""What the commands print, and where: every line on stderr is ``dftl-warp: ...`` (warnings
``dftl-warp: warning: ...``), so a log parser can tell the tool's lines from anything else; ``-q``
silences progress and notes but never a warning; closed standard streams end no command with a
traceback; a terminal that says TERM=dumb gets no progress bar."""

import io
import subprocess
import sys

import numpy as np
from usd_stages import add_curves, chain, new_stage
from test_usd_features import sphere_collider

from dftl_warp import cli


def combed_into_a_ball(path):
    """Three strands combed into a sphere collider: the clean start moves them out (a warning)."""
    stage = new_stage(path, start=1, end=3)
    d = np.array([1.0, -1.0, 0.0]) / np.sqrt(2)
    pts = np.concatenate([chain(12, 0.01, direction=d, origin=(0.0, 0.1, z)) for z in (-0.02, 0.0, 0.02)])
    add_curves(stage, "/World/Hair", pts, [12, 12, 12])
    sphere_collider(stage, "/World/Ball", 0.1)
    stage.Save()
    return path


def unprefixed(err: str) -> list[str]:
    return [line for line in err.splitlines() if not line.startswith("dftl-warp: ")]


def test_simulate_prefixes_the_clean_start_preroll_and_guides_lines(tmp_path, capsys):
    """The clean start's, the preroll's, the quality preset's and the guides' lines were printed
    bare ("clean start: 42 of 45000 particles ..."), unlike every other line of stderr."""
    src = combed_into_a_ball(tmp_path / "in.usda")
    assert cli.main(["simulate", str(src), "-o", str(tmp_path / "o.usdc"), "--device", "cpu", "--end", "2",
                     "--preroll", "0.1", "--guides", "2"]) == 0
    err = capsys.readouterr().err
    assert not unprefixed(err), err
    assert sum(line.startswith("dftl-warp: warning: clean start: ") and "started inside a collider" in line
               for line in err.splitlines()) == 1, err
    assert sum("preroll: " in line for line in err.splitlines()) == 1, err
    assert sum(line.startswith("dftl-warp: guides: ") for line in err.splitlines()) == 1, err
    src2 = tmp_path / "plain.usda"
    stage = new_stage(src2, start=1, end=3)
    add_curves(stage, "/World/Hair", chain(8, 0.01, direction=(0.0, -1.0, 0.0)), [8])
    stage.Save()
    assert cli.main(["simulate", str(src2), "-o", str(tmp_path / "p.usdc"), "--device", "cpu", "--end", "2",
                     "--preroll", "0.1"]) == 0
    err = capsys.readouterr().err
    assert not unprefixed(err), err
    assert sum(line.startswith("dftl-warp: preroll: ") and ", settled" in line for line in err.splitlines()) == 1, err


def test_simulate_quiet_keeps_every_warning(tmp_path, capsys):
    """-q dropped the warnings with the progress (the clean start's, a flag that does nothing, energy
    growth): render's -q and batch's --quiet keep them. Now -q is no progress and no notes."""
    src = combed_into_a_ball(tmp_path / "in.usda")
    assert cli.main(["simulate", str(src), "-o", str(tmp_path / "o.usdc"), "--device", "cpu", "--end", "2",
                     "--preroll", "0.1", "--guide-method", "kmeans", "-q"]) == 0
    captured = capsys.readouterr()
    err = captured.err.splitlines()
    assert all(line.startswith("dftl-warp: warning: ") for line in err), err
    assert sum("clean start: " in line and "started inside a collider" in line for line in err) == 1, err
    assert sum("--guide-method kmeans does nothing without --guides" in line for line in err) == 1, err
    assert not any("device" in line or "simulating" in line for line in err), err
    assert len(captured.out.splitlines()) == 1 and "o.usdc" in captured.out
    path = tmp_path / "unstable.usda"   # DFTL with s = 0 at 40 substeps pumps energy in (test_energy_warning)
    stage = new_stage(path, start=1, end=24)
    add_curves(stage, "/World/Hair", chain(64, 0.005, direction=(1.0, 0.0, 0.0)), [64])
    stage.Save()
    assert cli.main(["simulate", str(path), "-o", str(tmp_path / "u.usdc"), "--solver", "dftl", "--damping", "0",
                     "--substeps", "40", "--device", "cpu", "--quiet"]) == 0
    err = capsys.readouterr().err.splitlines()
    assert sum(line.startswith("dftl-warp: warning: ") and "energy grew" in line for line in err) == 1, err


def _closing(fd):
    import os

    return lambda: os.close(fd)


def test_closed_stdout_or_stderr_is_no_traceback(tmp_path):
    """`dftl-warp devices >&-` ended in AttributeError: 'NoneType' object has no attribute 'flush'
    (exit 1); with stderr closed (`2>&-`) Python's print(file=None) sent every message to stdout,
    mixed with the results. A closed stdout is a reader gone (141, as `| head` gives); a closed
    stderr loses the messages, not the results."""
    src = tmp_path / "in.usda"
    stage = new_stage(src, start=1, end=3)
    add_curves(stage, "/World/Hair", chain(8, 0.01, direction=(0.0, -1.0, 0.0)), [8])
    stage.Save()
    argv = [sys.executable, "-m", "dftl_warp"]
    r = subprocess.run([*argv, "devices"], stderr=subprocess.PIPE, text=True, preexec_fn=_closing(1), timeout=60)
    assert r.returncode == 141 and "Traceback" not in r.stderr, r.stderr
    out = tmp_path / "o.usda"
    r = subprocess.run([*argv, "simulate", str(src), "-o", str(out), "--device", "cpu", "--end", "2"],
                       stdout=subprocess.PIPE, text=True, preexec_fn=_closing(2), timeout=60)
    assert r.returncode == 0 and out.exists()
    assert r.stdout.splitlines() == [r.stdout.strip()] and r.stdout.startswith(str(out)), r.stdout


class _Terminal(io.StringIO):
    def isatty(self):
        return True


def test_no_progress_bar_on_a_dumb_terminal(monkeypatch):
    """TERM=dumb (Emacs shells, some CI consoles) cannot move the cursor: a bar's carriage returns
    and escape codes came out as one long garbled line. Such a terminal gets the plain lines."""
    from dftl_warp.output.progress import LineProgress, progress_bar

    monkeypatch.setenv("TERM", "dumb")
    assert isinstance(progress_bar(4, desc="simulating", file=_Terminal()), LineProgress)
    monkeypatch.setenv("TERM", "xterm-256color")
    bar = progress_bar(4, desc="simulating", file=_Terminal())
    assert not isinstance(bar, LineProgress)
    bar.close()


def test_import_quiet_keeps_its_warnings(tmp_path, capsys):
    """import -q dropped its warnings with the summary line (two strands with coincident points
    imported without a word); -q now leaves out the summary line only."""
    import test_importers as ti
    from test_import_input import COINCIDE, dup_file

    src, _ = dup_file(tmp_path)
    code, out, err = ti.run_cli(["import", str(src), "-o", str(tmp_path / "c.usda"), "-q"], capsys)
    assert code == 0 and out == ""
    lines = err.splitlines()
    assert lines and all(line.startswith("dftl-warp: warning: ") for line in lines), err
    assert sum(bool(COINCIDE.search(line)) for line in lines) == 1, err
