"""Bad input through the command line: one line naming file, prim and index; exit 2; no traceback;
no output file (and no partial file) left behind."""

import os
import subprocess
import sys

import numpy as np
import pytest
from usd_stages import USDA_HEAD, add_curves, chain, new_stage

from dftl_warp import cli
from dftl_warp.usd import read as usd_read


def run_cli(capsys, *argv):
    code = cli.main(["simulate", *map(str, argv), "--quiet"])
    out, err = capsys.readouterr()
    return code, out, err


def assert_refused(capsys, tmp_path, argv, *expected, output=None):
    """Exit 2, one stderr line with every expected piece, nothing written next to the output."""
    output = output or tmp_path / "out.usdc"
    before = set(os.listdir(output.parent)) if output.parent.is_dir() else set()
    code, out, err = run_cli(capsys, *argv, "-o", output)
    assert code == 2, err
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("dftl-warp: error: ")
    assert "Traceback" not in err
    for piece in expected:
        assert piece in lines[0], (piece, lines[0])
    after = set(os.listdir(output.parent)) if output.parent.is_dir() else set()
    assert after == before, f"left behind: {after - before}"
    return lines[0]


def curves_file(tmp_path, points, counts, name="in.usda", **kw):
    stage = new_stage(tmp_path / name)
    add_curves(stage, "/World/Hair", points, counts, **kw)
    stage.Save()
    return tmp_path / name


def test_nan_point_names_file_prim_and_index(tmp_path, capsys):
    pts = chain(5)
    pts[3, 1] = np.nan
    f = curves_file(tmp_path, pts, [5])
    assert_refused(capsys, tmp_path, [f], f"{f}: /World/Hair: points[3] = (3, nan, 0) is not finite")


def test_inf_point_names_its_index(tmp_path, capsys):
    pts = np.concatenate([chain(2), chain(4)])
    pts[4, 2] = -np.inf
    f = curves_file(tmp_path, pts, [2, 4])
    assert_refused(capsys, tmp_path, [f], f"{f}: /World/Hair: points[4]", "-inf", "not finite")


def test_counts_not_matching_points(tmp_path, capsys):
    f = curves_file(tmp_path, chain(5), [3, 3])
    assert_refused(capsys, tmp_path, [f], f"{f}: /World/Hair: curveVertexCounts sum to 6 but points has 5 entries")


@pytest.mark.parametrize("counts, index, value", [([3, 0, 2], 1, 0), ([5, -1, 1], 1, -1)])
def test_counts_below_one(tmp_path, capsys, counts, index, value):
    f = curves_file(tmp_path, chain(5), counts)
    assert_refused(capsys, tmp_path, [f],
                   f"{f}: /World/Hair: curveVertexCounts[{index}] = {value}: every curve needs at least 1 vertex")


def test_changing_topology_is_refused(tmp_path, capsys):
    f = curves_file(tmp_path, chain(4), [4])
    from pxr import Usd, Vt

    stage = Usd.Stage.Open(str(f))
    attr = stage.GetPrimAtPath("/World/Hair").GetAttribute("curveVertexCounts")
    attr.Set(Vt.IntArray([4]), 1.0)
    attr.Set(Vt.IntArray([2, 2]), 5.0)
    stage.Save()
    assert_refused(capsys, tmp_path, [f], f"{f}: /World/Hair: curveVertexCounts changes at time 5")


def test_periodic_curves_are_refused(tmp_path, capsys):
    f = curves_file(tmp_path, chain(4), [4], curve_type="cubic", basis="bspline", wrap="periodic")
    assert_refused(capsys, tmp_path, [f], f"{f}: /World/Hair: periodic curves")


def test_stage_without_curves(tmp_path, capsys):
    new_stage(tmp_path / "empty.usda").Save()
    f = tmp_path / "empty.usda"
    assert_refused(capsys, tmp_path, [f], f"{f}: the stage has no BasisCurves prims")


def test_curves_prim_without_curves(tmp_path, capsys):
    f = curves_file(tmp_path, np.zeros((0, 3)), [])
    assert_refused(capsys, tmp_path, [f], f"{f}: no curves to simulate")


def test_missing_file(tmp_path, capsys):
    f = tmp_path / "nope.usda"
    assert_refused(capsys, tmp_path, [f], f"{f}: no such file")


def test_unreadable_file(tmp_path, capsys, monkeypatch):
    f = curves_file(tmp_path, chain(3), [3])

    def denied(*args, **kwargs):
        raise PermissionError(13, "Permission denied")

    # the tests may run as root, who can read any file: make the reader's open() fail instead
    monkeypatch.setattr(usd_read, "open", denied, raising=False)
    assert_refused(capsys, tmp_path, [f], f"{f}: cannot read: Permission denied")


def test_directory_and_non_usd_inputs(tmp_path, capsys):
    (tmp_path / "d.usda").mkdir()
    assert_refused(capsys, tmp_path, [tmp_path / "d.usda"], "d.usda: is a directory")
    (tmp_path / "notes.txt").write_text("hello")
    assert_refused(capsys, tmp_path, [tmp_path / "notes.txt"], "notes.txt: not a USD file")


def test_syntax_error_names_line_and_column(tmp_path, capsys):
    f = tmp_path / "broken.usda"
    f.write_text('#usda 1.0\ndef BasisCurves "Hair" {\n    int[] curveVertexCounts = [2\n}\n')
    line = assert_refused(capsys, tmp_path, [f], f"{f}:4:1: syntax error")
    assert "pxrInternal" not in line


def test_corrupt_binary_file(tmp_path, capsys):
    f = tmp_path / "junk.usdc"
    f.write_bytes(b"not a crate file")
    assert_refused(capsys, tmp_path, [f], f"{f}: cannot open as a USD stage")


def test_unwritable_outputs(tmp_path, capsys):
    f = curves_file(tmp_path, chain(3), [3])
    # a missing output folder is created, as render and batch create theirs (issue 18, item 10)
    code, _, err = run_cli(capsys, f, "-o", tmp_path / "no" / "such" / "out.usdc")
    assert code == 0 and (tmp_path / "no" / "such" / "out.usdc").exists(), err
    (tmp_path / "dir.usdc").mkdir()
    assert_refused(capsys, tmp_path, [f], "dir.usdc: cannot write: is a directory", output=tmp_path / "dir.usdc")
    (tmp_path / "file").write_text("x")
    assert_refused(capsys, tmp_path, [f], "cannot write: folder", output=tmp_path / "file" / "out.usdc")
    assert_refused(capsys, tmp_path, [f], "output must end in", output=tmp_path / "out.usdz")
    assert_refused(capsys, tmp_path, [f], "would overwrite the input", output=f)


def test_stage_without_time_codes_needs_flags(tmp_path, capsys):
    stage = new_stage(tmp_path / "in.usda", start=None, end=None)
    add_curves(stage, "/World/Hair", chain(3), [3])
    stage.Save()
    f = tmp_path / "in.usda"
    assert_refused(capsys, tmp_path, [f], f"{f}: the stage has no startTimeCode/endTimeCode; give --start and --end")
    code, out, err = run_cli(capsys, f, "--start", 0, "--end", 3, "-o", tmp_path / "out.usdc")
    assert code == 0 and (tmp_path / "out.usdc").exists()


def test_empty_frame_range(tmp_path, capsys):
    f = curves_file(tmp_path, chain(3), [3])
    assert_refused(capsys, tmp_path, [f, "--start", 5, "--end", 2], "frame range 5..2 is empty")


def test_unknown_device(tmp_path, capsys):
    f = curves_file(tmp_path, chain(3), [3])
    assert_refused(capsys, tmp_path, [f, "--device", "cuda:7"], "--device cuda:7: not available")


def test_failure_while_writing_leaves_no_output_and_keeps_an_old_one(tmp_path, capsys, monkeypatch):
    """A run that dies mid-way (here: interrupted at frame 4) removes its partial file and leaves a
    previous OUTPUT untouched; while running, OUTPUT itself is never written."""
    from dftl_warp.output import usd as usd_write

    f = curves_file(tmp_path, chain(3), [3])
    out = tmp_path / "out.usdc"
    out.write_bytes(b"previous result")
    real = usd_write.UsdWriter.write_frame
    seen = []

    def interrupted(self, time_code, samples):
        seen.append((out.read_bytes(), self.partial.exists()))
        if time_code == 4:
            raise KeyboardInterrupt
        return real(self, time_code, samples)

    monkeypatch.setattr(usd_write.UsdWriter, "write_frame", interrupted)
    code, _, err = run_cli(capsys, f, "-o", out)
    assert code == 130 and err.strip() == "dftl-warp: interrupted"
    assert seen and all(old == b"previous result" and partial for old, partial in seen)
    assert out.read_bytes() == b"previous result"
    assert sorted(os.listdir(tmp_path)) == ["in.usda", "out.usdc"]


def test_console_script_prints_no_traceback(tmp_path):
    """The installed entry point, in a fresh process: one line on stderr, exit status 2."""
    pts = chain(4)
    pts[2, 0] = np.inf
    f = curves_file(tmp_path, pts, [4])
    proc = subprocess.run(
        [sys.executable, "-m", "dftl_warp", "simulate", str(f), "-o", str(tmp_path / "o.usdc")],
        capture_output=True, text=True, timeout=120,
    )
    assert proc.returncode == 2
    assert proc.stderr.strip() == f"dftl-warp: error: {f}: /World/Hair: points[2] = (inf, 0, 0) is not finite"
    assert not (tmp_path / "o.usdc").exists()


def test_a_cache_whose_input_moved_says_which_layer_did_not_load(tmp_path, capsys):
    """A stage whose only hair is in a sublayer that is gone (a cache whose input was moved):
    the refusal names the missing layer, not only "no BasisCurves prims"."""
    f = tmp_path / "cache.usda"
    f.write_text('#usda 1.0\n(\n    subLayers = [@./moved_away.usda@]\n)\n')
    line = assert_refused(capsys, tmp_path, [f], f"{f}: the stage has no BasisCurves prims (no hair to simulate) "
                                                 "(USD: Could not load sublayer")
    assert "moved_away.usda" in line


def _indexed_widths_stage(path, indices):
    path.write_text(USDA_HEAD + f"""def BasisCurves "Hair"
{{
    uniform token type = "linear"
    int[] curveVertexCounts = [3, 3]
    point3f[] points = [(0, 0, 0), (0, -0.1, 0), (0, -0.2, 0), (0.1, 0, 0), (0.1, -0.1, 0), (0.1, -0.2, 0)]
    float[] primvars:widths = [0.0001, 0.0002] (interpolation = "vertex")
    int[] primvars:widths:indices = {list(indices)}
}}
""")
    return path


def test_indexed_widths_out_of_range_are_one_line_for_simulate_and_render(tmp_path, capsys):
    """An index past the widths' values was USD's two-line warning on the terminal, and the prim
    then ran with no widths (the DFTL chain instead of elastic hair) without a word."""
    bad = _indexed_widths_stage(tmp_path / "bad.usda", [0, 1, 0, 1, 0, 5])
    assert_refused(capsys, tmp_path, [bad, "--end", 2],
                   f"{bad}: /Hair", "primvars:widths:indices[5] = 5 is out of range (2 values)")
    code = cli.main(["render", str(bad), "--resolution", "16x12", "--spp", "1", "-q", "-o", str(tmp_path / "b.png")])
    err = capsys.readouterr().err
    assert code == 2 and "primvars:widths:indices[5] = 5 is out of range" in err and len(err.strip().splitlines()) == 1
    good = _indexed_widths_stage(tmp_path / "good.usda", [0, 1, 0, 1, 0, 1])
    assert cli.main(["info", str(good)]) == 0
    out = capsys.readouterr().out
    assert "elastic" in out, out
