"""The energy-growth warning of `dftl-warp simulate` (dftl_warp.simulation.monitor) as a user sees it.

- Hair moved out of a collider by the clean start is not "energy from nowhere": the budget starts
  from the state the clean start leaves (it started from the authored state, and a strand pushed
  out of a head warned although it never moved afterwards).
- The warning's energy is in J/kg whatever the stage's units: the same unstable scene in metres
  and in millimetres reports the same value.
"""

import numpy as np
import pytest
from usd_stages import add_curves, chain, new_stage
from test_usd_features import sphere_collider

from dftl_warp import cli


def grown_lines(err: str) -> list[str]:
    return [line for line in err.splitlines() if "energy grew" in line]


@pytest.mark.parametrize("solver", ["elastic", "dftl"])
def test_hair_pushed_out_by_the_clean_start_is_not_energy_growth(tmp_path, capsys, solver):
    stage = new_stage(tmp_path / "in.usda", start=1, end=4)
    d = np.array([1.0, -1.0, 0.0]) / np.sqrt(2)   # combed into the ball, up to 4 cm deep
    pts = np.concatenate([chain(12, 0.01, direction=d, origin=(0.0, 0.1, z)) for z in (-0.02, 0.0, 0.02)])
    add_curves(stage, "/World/Hair", pts, [12, 12, 12], widths=0.002, bending=True)
    sphere_collider(stage, "/World/Ball", 0.1)
    stage.Save()
    assert cli.main(["simulate", str(tmp_path / "in.usda"), "-o", str(tmp_path / "out.usdc"),
                     "--solver", solver]) == 0
    err = capsys.readouterr().err
    assert "clean start:" in err and "started inside a collider" in err, err
    assert not grown_lines(err), err


def test_energy_warning_is_in_joules_per_kilogram_in_any_stage_units(tmp_path, capsys):
    """DFTL with s = 0 at 40 substeps a frame pumps energy into a horizontal chain (test_stability);
    the stage in metres and the same stage in millimetres warn with the same energies."""
    values = {}
    for units, mpu in (("m", 1.0), ("mm", 0.001)):
        path = tmp_path / f"{units}.usda"
        stage = new_stage(path, start=1, end=24, meters_per_unit=mpu)
        add_curves(stage, "/World/Hair", chain(64, 0.005 / mpu, direction=(1.0, 0.0, 0.0)), [64])
        stage.Save()
        assert cli.main(["simulate", str(path), "-o", str(tmp_path / f"{units}.usdc"), "--solver", "dftl",
                         "--damping", "0", "--substeps", "40"]) == 0
        lines = grown_lines(capsys.readouterr().err)
        assert len(lines) == 1 and str(path) in lines[0] and "use s = 1" in lines[0], lines
        grew = lines[0].split("energy grew to ")[1]
        values[units] = (float(grew.split(" J/kg")[0]), grew.split(" at frame ")[1].split(",")[0])
    (joules_m, frame_m), (joules_mm, frame_mm) = values["m"], values["mm"]
    assert frame_m == frame_mm and joules_m == pytest.approx(joules_mm, rel=2e-3), values


@pytest.mark.parametrize("feature", ["dftl:hairHair", "dftl:wind"])
def test_scenes_with_energy_sources_say_the_check_is_off_instead_of_calling_it_unstable(tmp_path, capsys, feature):
    """Wind and hair-hair's repulsion add energy the monitor cannot account for (a groom's edge at
    rest is pushed out by the repulsion; the wind blows): the run says once that there is no energy
    check, and never calls the setting unstable; a scene without them keeps the check."""
    from pxr import Gf, Sdf

    stage = new_stage(tmp_path / "in.usda", start=1, end=12)
    rng = np.random.default_rng(0)
    pts = np.concatenate([chain(12, 0.01, direction=(rng.uniform(-0.3, 0.3), -1.0, rng.uniform(-0.3, 0.3)),
                                origin=(0.002 * (k % 8), 0.0, 0.002 * (k // 8))) for k in range(64)])
    curves = add_curves(stage, "/World/Hair", pts, [12] * 64, widths=1e-4)
    world = stage.GetPrimAtPath("/World")
    if feature == "dftl:hairHair":
        world.CreateAttribute("dftl:hairHair", Sdf.ValueTypeNames.Bool, custom=True).Set(True)
    else:
        world.CreateAttribute("dftl:wind", Sdf.ValueTypeNames.Float3, custom=True).Set(Gf.Vec3f(3.0, 0.0, 0.0))
        curves.GetPrim().CreateAttribute("dftl:drag", Sdf.ValueTypeNames.Float, custom=True).Set(2.0)
    stage.Save()
    assert cli.main(["simulate", str(tmp_path / "in.usda"), "-o", str(tmp_path / "out.usdc"),
                     "--solver", "dftl"]) == 0
    err = capsys.readouterr().err
    assert not grown_lines(err), err
    notes = [line for line in err.splitlines() if "no energy check" in line]
    assert len(notes) == 1 and "/World/Hair" in notes[0], err
    assert ("hair-hair's repulsion adds" if feature == "dftl:hairHair" else "the wind adds") in notes[0], notes
