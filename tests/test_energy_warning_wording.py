"""The energy warning names moving colliders among what could supply a strand's energy only when one
reached that strand.

Before, the warning said '... more than X J/kg (2x what it started with and its root and moving
colliders can supply)' whenever the scene had colliders, even a static ball 1 m below the hair and a
sphere 3 m away; the budget of such a strand counts its root alone (the monitor records, per strand,
the speed of the moving colliders that reached it: ``EnergyMonitor.collider_speed``).
"""

from __future__ import annotations

import numpy as np
import pytest
from test_energy_warning_colliders import FPS, _unstable_stage, add_collider, grown_lines
from usd_stages import add_curves, chain, new_stage

from dftl_warp import cli

ROOT_ONLY = "(2x what it started with and its root can supply)"
WITH_COLLIDERS = "(2x what it started with and its root and moving colliders can supply)"
UNSTABLE = ["--solver", "dftl", "--damping", "0", "--substeps", "40"]   # pumps energy in (test_energy_warning)


def _warning(tmp_path, capsys, path, device="cpu") -> str:
    assert cli.main(["simulate", path, "-o", str(tmp_path / "o.usdc"), "--device", device, *UNSTABLE]) == 0
    lines = grown_lines(capsys.readouterr().err)
    assert len(lines) == 1, lines
    return lines[0]


def _near_and_far(path, far: bool) -> str:
    """A horizontal chain with a sphere moving slowly (5 cm/s) 30 cm below it, within its reach; with
    ``far``, a second chain 2 m away, out of the sphere's reach."""
    stage = new_stage(path, start=1, end=12)
    origins = [(0.0, 0.0, 0.0)] + ([(0.0, 0.0, 2.0)] if far else [])
    add_curves(stage, "/World/Hair", np.concatenate([chain(64, 0.005, (1.0, 0.0, 0.0), o) for o in origins]),
               [64] * len(origins))
    add_collider(stage, "sphere", lambda f: np.array([0.15, -0.3, -0.1 + 0.05 * f / FPS]))
    stage.Save()
    return str(path)


def test_static_and_distant_colliders_are_not_named(tmp_path, capsys):
    line = _warning(tmp_path, capsys, _unstable_stage(tmp_path / "in.usda", colliders=True))
    assert ROOT_ONLY in line and "collider" not in line, line


def test_a_moving_collider_that_reached_the_strand_is_named(tmp_path, capsys):
    line = _warning(tmp_path, capsys, _near_and_far(tmp_path / "in.usda", far=False))
    assert "strand 0" in line and WITH_COLLIDERS in line, line


@pytest.mark.parametrize("device", ["cpu", "cpu,cpu"])
def test_the_named_strand_decides(tmp_path, capsys, device):
    """The worst strand (the one out of the sphere's reach: its budget is its root's alone) is named,
    with what could supply it, on one device and split over two (its part's records)."""
    line = _warning(tmp_path, capsys, _near_and_far(tmp_path / "in.usda", far=True), device)
    assert "strand 1 (and 1 more)" in line and ROOT_ONLY in line, line
