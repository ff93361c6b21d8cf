"""`dftl-warp simulate`: quality presets, pbd iterations and the energy-growth warning."""

import numpy as np
from pxr import Usd, UsdGeom

from dftl_warp.cli import main
from usd_stages import add_curves, new_stage


def hanging_stage(path, particles=128, frames=24):
    """One strand hanging at rest from the origin (0.2 m), its tip nudged by 20 micrometres."""
    stage = new_stage(path, start=1, end=frames)
    pts = np.zeros((particles, 3))
    pts[:, 1] = -np.linspace(0.0, 0.2, particles)
    pts[:, 0] = 2e-5 * np.linspace(0.0, 1.0, particles) ** 2
    add_curves(stage, "/World/Hair", pts, [particles])
    stage.GetRootLayer().Save()
    return path


def written_points(path, frame):
    stage = Usd.Stage.Open(str(path))
    return np.array(UsdGeom.BasisCurves(stage.GetPrimAtPath("/World/Hair")).GetPointsAttr().Get(frame))


def test_damping_below_one_at_small_steps_warns_once_naming_the_setting(tmp_path, capsys):
    scene = hanging_stage(tmp_path / "hang.usda")
    # s = 0.8 at dt = 1/(24 * 417) ~ 1e-4 s pumps energy into the strand (docs/accuracy.md)
    assert main(["simulate", str(scene), "-o", str(tmp_path / "bad.usdc"), "--damping", "0.8",
                 "--substeps", "417"]) == 0
    err = capsys.readouterr().err
    warnings = [line for line in err.splitlines() if "warning" in line and "energy" in line]
    assert len(warnings) == 1
    assert "damping=0.8" in warnings[0] and "417 substeps/frame" in warnings[0] and "/World/Hair" in warnings[0]
    assert "Traceback" not in err

    # the same small step with s = 1 is stable: no warning
    assert main(["simulate", str(scene), "-o", str(tmp_path / "good.usdc"), "--substeps", "417"]) == 0
    assert "energy" not in capsys.readouterr().err


def test_quality_preset_sets_solver_substeps_and_precision(tmp_path, capsys):
    scene = hanging_stage(tmp_path / "hang.usda", particles=8, frames=3)
    out = tmp_path / "draft.usdc"
    assert main(["simulate", str(scene), "-o", str(out), "--quality", "draft", "--quiet"]) == 0
    from dftl_warp.simulation.simulate import simulate_usd

    reference = simulate_usd(str(scene), str(tmp_path / "explicit.usdc"), substeps=16, solver="dftl")
    assert reference.groups[0]["substeps"] == 16
    assert np.array_equal(written_points(out, 3), written_points(tmp_path / "explicit.usdc", 3))
    # an explicit flag overrides the preset's part
    out2 = tmp_path / "draft4.usdc"
    assert main(["simulate", str(scene), "-o", str(out2), "--quality", "draft", "--substeps", "4", "--quiet"]) == 0
    assert not np.array_equal(written_points(out2, 3), written_points(out, 3))


def test_pbd_iterations_flag_changes_the_result(tmp_path):
    scene = hanging_stage(tmp_path / "hang.usda", particles=8, frames=3)
    runs = {}
    for k in (1, 8):
        out = tmp_path / f"pbd{k}.usdc"
        assert main(["simulate", str(scene), "-o", str(out), "--solver", "pbd", "--iterations", str(k),
                     "--quiet"]) == 0
        runs[k] = written_points(out, 3)
    assert np.isfinite(runs[1]).all() and not np.array_equal(runs[1], runs[8])


def test_quality_preset_keeps_the_elastic_solver_of_prims_with_widths(tmp_path, capsys):
    """A preset's solver is for the chains it was measured on: a prim with widths (an elastic rod by
    default) keeps the elastic solver and takes the preset's substeps; a chain takes the preset's
    solver. The run says so."""
    from dftl_warp.simulation.simulate import simulate_usd

    path = tmp_path / "two.usda"
    stage = new_stage(path, start=1, end=2)
    pts = np.zeros((6, 3))
    pts[:, 1] = -np.linspace(0.0, 0.02, 6)
    add_curves(stage, "/World/Styled", pts, [6], widths=[8e-5] * 6, bending=None)   # elastic by default
    add_curves(stage, "/World/Chain", pts + [0.1, 0, 0], [6])                        # no widths: the chain
    stage.GetRootLayer().Save()
    summary = simulate_usd(str(path), str(tmp_path / "out.usdc"), quality="draft", substeps=16, damping=1.0,
                           correction="prior", precision="float32")
    # one prim per group; only /World/Styled has widths, so the elastic group is it
    assert sorted((g["solver"], g["substeps"], g["prims"]) for g in summary.groups) == [("dftl", 16, 1),
                                                                                        ("elastic", 16, 1)]
    assert any("1 prim with widths keeps the elastic solver" in w for w in summary.warnings)
    reference = simulate_usd(str(path), str(tmp_path / "ref.usdc"), quality="reference", substeps=16,
                             precision="float32")
    assert {g["solver"] for g in reference.groups} == {"elastic", "rattle"}
    # through the command line: the preset's note, then the run
    assert main(["simulate", str(path), "-o", str(tmp_path / "cli.usdc"), "--quality", "draft", "--quiet"]) == 0
