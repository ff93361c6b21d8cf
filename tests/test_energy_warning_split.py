"""The energy-growth warning names the same strand on one device and several, as its prim's strand.

Before, a groom split over devices warned for the first part that went over its budget, naming that
part's own strand index and counting only its strands ('strand 16 (and 40 more)' where one device said
'strand 61 (and 84 more)'); and a group of several prims named the strand by its index in the group
('strand 4' of '/World/A, /World/B', for strand 1 of /World/B).
"""

from __future__ import annotations

import numpy as np
from usd_stages import add_curves, chain, new_stage

from dftl_warp import cli


def test_energy_warning_names_the_prims_strand_alike_on_one_device_and_two(tmp_path, capsys):
    path = tmp_path / "in.usda"
    stage = new_stage(path, start=1, end=12)
    # DFTL with s = 0 at 40 substeps a frame pumps energy into horizontal chains (test_stability)
    add_curves(stage, "/World/A", np.concatenate([chain(n, 0.005, origin=(0, 0, 0.01 * k))
                                                  for k, n in enumerate((40, 8, 40))]), [40, 8, 40])
    add_curves(stage, "/World/B", np.concatenate([chain(n, 0.005, origin=(0, 0.1, 0.01 * k))
                                                  for k, n in enumerate((24, 64))]), [24, 64])
    stage.Save()
    lines = {}
    for device in ("cpu", "cpu,cpu"):
        assert cli.main(["simulate", str(path), "-o", str(tmp_path / f"{device}.usdc"), "--solver", "dftl",
                         "--damping", "0", "--substeps", "40", "--device", device, "--quiet"]) == 0
        lines[device] = [line for line in capsys.readouterr().err.splitlines() if "energy grew" in line]
    assert len(lines["cpu"]) == 1, lines
    assert ": /World/B strand 1" in lines["cpu"][0], lines["cpu"]
    assert lines["cpu,cpu"] == lines["cpu"]
