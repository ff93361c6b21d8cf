"""``simulate`` says what it ignores or approximates in the input before the frames run.

Before, the input's warnings (an unknown ``dftl:`` attribute, frames ``--frame-step`` leaves out, a
collider that keeps its size, a flag that does nothing here) were printed only after the whole run:
a TD starting a two-hour run learnt at its end that an attribute had been ignored. Now they come
with the device line, before the first frame, once each; with ``-q`` they come after the run, with
the other warnings, as documented. Warnings that arise while running (energy growth) still come as
they arise.
"""

from __future__ import annotations

import numpy as np
from pxr import Sdf
from test_usd_features import sphere_collider
from usd_stages import add_curves, animated_xform, chain, new_stage

from dftl_warp import cli

#: a piece of each input warning the stage and flags below give
INPUT_WARNINGS = ("dftl:bogus", "--frame-step 2: frames 1..4 end between written frames",
                  "radius is time-sampled: the collider keeps its size",
                  "--arithmetic float64 does nothing here",
                  "lie partly outside the stage's time range 1..3")


def _stage(path):
    stage = new_stage(path, start=1, end=3)
    animated_xform(stage, "/World/Head", translate={1: (0, 0, 0), 3: (0.01, 0, 0)})
    curves = add_curves(stage, "/World/Head/Hair", chain(6, 0.02, direction=(0.0, -1.0, 0.0)), [6])
    curves.GetPrim().CreateAttribute("dftl:bogus", Sdf.ValueTypeNames.Float, custom=True).Set(1.0)
    ball = sphere_collider(stage, "/World/Ball", 0.05, translate=(0.5, 0.0, 0.0))
    ball.GetRadiusAttr().Set(0.05, 1)
    ball.GetRadiusAttr().Set(0.06, 3)
    stage.Save()
    return str(path)


def _run(tmp_path, capsys, *extra):
    argv = ["simulate", _stage(tmp_path / "in.usda"), "-o", str(tmp_path / "o.usdc"), "--device", "cpu",
            "--solver", "dftl", "--end", "4", "--frame-step", "2", "--arithmetic", "float64", *extra]
    assert cli.main(argv) == 0
    return capsys.readouterr().err.splitlines()


def _where(lines, piece):
    return [k for k, line in enumerate(lines) if piece in line]


def test_input_warnings_come_before_the_frames_once_each(tmp_path, capsys):
    lines = _run(tmp_path, capsys)
    ran = _where(lines, "dftl-warp: simulating: ")
    device = _where(lines, "dftl-warp: device")
    assert ran and device, lines
    for piece in INPUT_WARNINGS:
        found = _where(lines, piece)
        assert len(found) == 1, (piece, lines)
        assert lines[found[0]].startswith("dftl-warp: warning: "), lines[found[0]]
        assert found[0] < device[0] < ran[0], (piece, lines)   # with the set-up lines, before the device line
    warned = [line for line in lines if line.startswith("dftl-warp: warning: ")]
    assert len(warned) == len(set(warned)), lines   # nothing said twice


def test_quiet_gives_the_input_warnings_once_after_the_run(tmp_path, capsys):
    lines = _run(tmp_path, capsys, "-q")
    assert all(line.startswith("dftl-warp: warning: ") for line in lines), lines
    for piece in INPUT_WARNINGS:
        assert len(_where(lines, piece)) == 1, (piece, lines)
    assert len(lines) == len(set(lines)), lines

