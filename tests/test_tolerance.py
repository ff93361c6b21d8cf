"""``--tolerance``: the error of the run against a converged reference is within [0.25, 2] x the
tolerance, for two tolerances a decade apart (issue 19), on the falling chain and a groom on a
turning head. The issue's third scene, a groom with a collider, is not met yet (only DFTL collides,
and at 0.002 in a 0.2 strand it needs more than the ladder's 1024 substeps: 2.1x and 10x the
tolerance measured); it is not tested here until it is.

"Error" is what the estimator estimates (dftl_warp.simulation.tolerance): the RMS over every
particle of the position difference (stage units; the RMS position error over strand length),
maximum over the frames. The reference is the reference solver (RATTLE, float64) at 512 substeps
per frame."""

import numpy as np
import pytest

from dftl_warp.simulation.simulate import simulate_usd
from dftl_warp.simulation.tolerance import RECORD
from dftl_warp.study import scenarios as sc
from usd_stages import add_curves, animated_xform, chain, composed_samples, new_stage


def falling_chain(path):
    """Four horizontal chains of 12 particles, 0.3 long, released under gravity for 12 frames."""
    stage = new_stage(path, start=1, end=12)
    pts = np.concatenate([chain(12, 0.3 / 11, origin=(0.0, 0.0, 0.05 * z)) for z in range(4)])
    add_curves(stage, "/World/Chain", pts, [12] * 4)
    stage.Save()


def turning_head(path):
    """24 strands of 8 particles, 0.15 long, hanging from a head whose transform turns about Y."""
    stage = new_stage(path, start=1, end=12)
    animated_xform(stage, "/World/Head", rotate_y={1: 0.0, 6: 40.0, 12: -20.0})
    pts, counts = sc.groom(strands=24, particles=8, length=0.15, head_radius=0.1)
    add_curves(stage, "/World/Head/Hair", pts, counts)
    stage.Save()


SCENES = {"falling_chain": (falling_chain, "/World/Chain"), "turning_head": (turning_head, "/World/Head/Hair")}


def frames(path, prim):
    samples = composed_samples(path, prim)
    return np.stack([samples[t] for t in sorted(samples)])


def reference(tmp_path, name):
    build, prim = SCENES[name]
    src = tmp_path / f"{name}.usda"
    build(src)
    out = tmp_path / f"{name}_ref.usdc"
    simulate_usd(src, out, solver="reference", precision="float64", substeps=512, device="cpu", monitor=False)
    return src, frames(out, prim)


def error(x, ref):
    return float(np.sqrt(((x - ref) ** 2).sum(-1).mean(-1)).max())


@pytest.mark.parametrize("name,tolerances", [
    ("falling_chain", (0.01, 0.001)),
    ("turning_head", (0.01, 0.001)),
])
def test_actual_error_within_a_quarter_and_twice_the_tolerance(tmp_path, name, tolerances):
    src, ref = reference(tmp_path, name)
    prim = SCENES[name][1]
    for tol in tolerances:
        out = tmp_path / f"{name}_{tol}.usdc"
        summary = simulate_usd(src, out, tolerance=tol, device="cpu")
        actual = error(frames(out, prim), ref)
        assert 0.25 * tol <= actual <= 2.0 * tol, (name, tol, actual / tol, summary.tolerance)
        # the estimate per frame is in the output, and the run says what it chose
        from dftl_warp.output.usd import UsdWriter

        rec = UsdWriter.read_record(out, RECORD)
        assert rec["tolerance"] == pytest.approx(tol)
        estimates = [float(e) for e in rec["group0.error"].split()]
        assert len(estimates) == 11 and rec["group0.max_error"] == pytest.approx(max(estimates), rel=1e-5)
        assert any("substeps per frame" in line for line in summary.tolerance)


def test_the_flag_is_in_the_table_and_checked(tmp_path):
    from dftl_warp.options import OPTIONS, OptionError

    assert OPTIONS["tolerance"].cli == "--tolerance" and OPTIONS["tolerance"].usd is None
    falling_chain(tmp_path / "in.usda")
    with pytest.raises(OptionError, match="tolerance must be"):
        simulate_usd(tmp_path / "in.usda", tmp_path / "o.usdc", tolerance=0.0, device="cpu")


def test_cli_prints_what_it_chose(tmp_path, capsys):
    from dftl_warp import cli

    falling_chain(tmp_path / "in.usda")
    assert cli.main(["simulate", str(tmp_path / "in.usda"), "-o", str(tmp_path / "o.usdc"), "--device", "cpu",
                     "--tolerance", "0.01", "--quiet"]) == 0
    err = capsys.readouterr().err
    assert "tolerance 0.01" in err and "rattle" in err
