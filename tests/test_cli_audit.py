"""Command-line contract cases found by a bad-input audit (2026-11-28): no command is a failure,
--substeps beside --tolerance is named as unused, a broken QC gate's line names the input, diff
names a cache's first point that is not finite, and import makes the output's folders."""

import numpy as np
from pxr import Usd, UsdGeom
from usd_stages import add_curves, chain, new_stage

from dftl_warp import cli


def hair(path, strands=4, vertices=5):
    stage = new_stage(path, start=1, end=3)
    pts = np.concatenate([chain(vertices, 0.02, origin=(0.05 * s, 0.0, 0.0)) for s in range(strands)])
    add_curves(stage, "/World/Hair", pts, [vertices] * strands)
    stage.Save()
    return str(path)


def run(capsys, *argv):
    code = cli.main([*map(str, argv)])
    out, err = capsys.readouterr()
    return code, out, err


def test_no_command_is_a_failure_with_one_error_line(capsys):
    code, out, err = run(capsys)
    assert code == 2 and out == ""
    assert err.strip().splitlines()[-1] == "dftl-warp: error: no command given (simulate, render, info, ...)"
    assert "Traceback" not in err


def test_substeps_beside_tolerance_is_named_as_unused(tmp_path, capsys):
    src = hair(tmp_path / "h.usda")
    code, out, err = run(capsys, "simulate", src, "-o", tmp_path / "o.usda", "--device", "cpu", "--end", "2",
                         "--solver", "dftl", "--tolerance", "0.001", "--substeps", "4", "-q")
    assert code == 0 and (tmp_path / "o.usda").exists()
    assert err.count("--substeps 4 with --tolerance 0.001: the tolerance chooses the shot's substeps per frame; "
                     "--substeps is not used") == 1
    assert "substeps per frame (mean" in err   # what it chose: the run's result, printed with -q too
    code, out, err = run(capsys, "simulate", src, "-o", tmp_path / "o2.usda", "--device", "cpu", "--end", "2",
                         "--solver", "dftl", "--tolerance", "0.001")
    assert code == 0 and "substeps per frame (mean" in err and "--substeps" not in err
    code, out, err = run(capsys, "simulate", src, "-o", tmp_path / "o3.usda", "--device", "cpu", "--end", "2",
                         "--solver", "dftl", "--tolerance", "0.001", "--substeps", "4", "--preroll", "0.05", "-q")
    assert code == 0 and "--substeps is only the preroll's" in err


def test_a_broken_gate_names_the_input_and_leaves_no_output(tmp_path, capsys):
    src = hair(tmp_path / "h.usda")
    out_path = tmp_path / "o.usdc"
    code, out, err = run(capsys, "simulate", src, "-o", out_path, "--device", "cpu", "--end", "3", "--solver", "dftl",
                         "--check", "speed<1e-12", "-q")
    assert code == 3 and not out_path.exists()
    assert err.count("\n") == 1 and err.startswith(f"dftl-warp: error: {src}: QC gate speed<1e-12 broken at frame ")


def test_diff_names_the_first_point_that_is_not_finite(tmp_path, capsys):
    paths = []
    for name, bad in (("a.usda", None), ("b.usda", 5)):
        stage = new_stage(tmp_path / name, start=1, end=2)
        pts = np.concatenate([chain(4, 0.1, origin=(0.0, 0.0, 0.2 * s)) for s in range(2)])
        add_curves(stage, "/World/Hair", pts, [4, 4])
        attr = UsdGeom.BasisCurves(stage.GetPrimAtPath("/World/Hair")).GetPointsAttr()
        for f in (1, 2):
            p = pts + 0.01 * f
            if bad is not None:
                p[bad:bad + 2, 1] = np.nan
            attr.Set([tuple(map(float, x)) for x in p], Usd.TimeCode(f))
        stage.Save()
        paths.append(str(tmp_path / name))
    code, out, err = run(capsys, "diff", *paths)
    assert code == 1 and "first difference beyond 0 stage units: frame 1, /World/Hair (nan)" in out
    assert err.strip().splitlines() == [f"dftl-warp: warning: {paths[1]}: /World/Hair: points[5] at frame 1 is not "
                                        "finite (2 points)"]


def test_import_makes_the_output_folders_as_simulate_does_and_removes_them_on_failure(tmp_path, capsys):
    import test_importers as ti

    src = ti.write_hair(tmp_path / "g.hair", np.concatenate([chain(4, 0.5, origin=(s, 0.0, 0.0)) for s in range(3)]),
                        [4, 4, 4], None)
    code, out, err = run(capsys, "import", src, "-o", tmp_path / "a" / "b" / "o.usda")
    assert code == 0 and (tmp_path / "a" / "b" / "o.usda").exists(), err
    (tmp_path / "bad.hair").write_bytes(b"HAIR" + b"\xff" * 40)   # a header cut short: refused while reading
    code, out, err = run(capsys, "import", tmp_path / "bad.hair", "-o", tmp_path / "c" / "d" / "o.usda")
    assert code == 2 and not (tmp_path / "c").exists() and err.count("\n") == 1


def test_diff_gives_the_reason_a_stage_cannot_open(tmp_path, capsys):
    a = hair(tmp_path / "a.usda")
    b = tmp_path / "b.usda"
    b.write_bytes(open(a, "rb").read().replace(b"def Xform", b"# caf\xe9\ndef Xform", 1))
    code, out, err = run(capsys, "diff", a, b)
    assert code == 2 and out == "" and err.count("\n") == 1
    assert err.startswith(f"dftl-warp: error: {b}: cannot open as a USD stage: not valid UTF-8 (byte 0xe9 at line ")
