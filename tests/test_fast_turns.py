"""A prim that turns faster than its once-a-frame root path can follow is said, once.

The roots' C1 path takes its velocities from fourth-order differences of the frames' positions; on
a circle sampled every theta they come out (8 sin theta - sin 2 theta) / (6 theta) of the speed
(0.31 at 150 degrees a frame). A head spinning 10 turns a second at 24 fps was simulated with roots
a third as fast, and nothing said so."""

import math

import numpy as np
import pytest
from usd_stages import add_curves, animated_xform, chain, new_stage

from dftl_warp import cli
from dftl_warp.simulation.root_paths import turn_degrees


def spinning(path, degrees_per_frame):
    stage = new_stage(path, start=1, end=4)
    animated_xform(stage, "/World/Head", rotate_y={f: degrees_per_frame * (f - 1) for f in range(1, 5)})
    add_curves(stage, "/World/Head/Hair", chain(5, 0.01, origin=(0.1, 0, 0), direction=(0, -1, 0)), [5])
    stage.Save()
    return path


@pytest.mark.parametrize("degrees, warned", [(60.0, False), (150.0, True)])
def test_a_prim_turning_faster_than_its_root_path_follows_is_one_warning(tmp_path, capsys, degrees, warned):
    src = spinning(tmp_path / "spin.usda", degrees)
    assert cli.main(["simulate", str(src), "-o", str(tmp_path / "out.usdc"), "--device", "cpu"]) == 0
    lines = [line for line in capsys.readouterr().err.splitlines() if "sampled once a frame" in line]
    if not warned:
        assert lines == []
        return
    assert len(lines) == 1, lines
    assert f"{src}: /World/Head/Hair: turns 150 degrees from frame 1 to 2 (more than 90)" in lines[0]


def test_turn_degrees_is_the_rotation_angle_whatever_the_scale():
    def rot_y(deg, scale=1.0):
        a = math.radians(deg)
        m = np.eye(4)
        m[:3, :3] = scale * np.array([[math.cos(a), 0, -math.sin(a)], [0, 1, 0], [math.sin(a), 0, math.cos(a)]])
        return m

    assert turn_degrees(rot_y(10.0), rot_y(160.0, scale=3.0)) == pytest.approx(150.0)
    assert turn_degrees(rot_y(0.0), rot_y(0.0, scale=0.5)) == pytest.approx(0.0, abs=1e-6)
