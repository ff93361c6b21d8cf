"""`dftl-warp study --front`: the front at scale, on a small groom on the CPU (issue 19).

The physics checks compare every solver with the converged float64 reference (the truth at 64
substeps per frame): the reference converges onto it, DFTL's error falls as its step shrinks, and
the preset picker and the Pareto front select what their definitions say on hand-made rows.
"""

import json

import numpy as np
import pytest

from dftl_warp.cli import main
from dftl_warp.study.front import (PRESET_TARGETS, pareto_front, pick_presets, preset_dict, preset_ineligible,
                                   presets_source, released_groom)


@pytest.fixture(scope="module")
def smoke(tmp_path_factory):
    """The CPU smoke run: 64 strands x 32 particles, 3 frames, a few settings of every solver."""
    out = tmp_path_factory.mktemp("front")
    assert main(["study", "--front", "--fast", "--strands", "64", "--frames", "3", "--device", "cpu",
                 "--out", str(out), "--quiet"]) == 0
    return out, json.loads((out / "front.json").read_text())


def row(label, solver, ms, error, substeps=8, stretch=1e-6, options=None, precision="float32"):
    return {"label": label, "solver": solver, "precision": precision, "options": dict(options or {}),
            "substeps": substeps, "ms_per_frame": ms, "error": error, "max_stretch": stretch, "finite": True}


def test_smoke_run_writes_json_markdown_and_plot(smoke):
    out, data = smoke
    assert (out / "front.png").read_bytes()[:4] == b"\x89PNG"
    md = (out / "front.md").read_text()
    assert "dftl-warp study --front --fast --strands 64 --frames 3 --device cpu" in md  # the command
    assert "CPU (Warp device `cpu`)" in md and data["meta"]["device_name"] == "CPU"  # the device
    assert data["meta"]["date"][:4].isdigit() and data["meta"]["date"] in md  # the date
    assert "![error against ms/frame](front.png)" in md and "## Quality presets from the front" in md
    solvers = {r["solver"] for r in data["result"]["rows"]}
    assert solvers == {"dftl", "pbd", "rattle", "reference"}
    rows = data["result"]["rows"]
    assert data["front"] == pareto_front(rows) and data["front"]
    assert all(r["finite"] and r["ms_per_frame"] > 0 for r in rows)


def test_physics_on_the_small_groom(smoke):
    _, data = smoke
    rows = {(r["label"], r["substeps"]): r for r in data["result"]["rows"]}
    dftl = [rows[("DFTL prior s=1 f32", k)]["error"] for k in (1, 8, 64)]
    ref = rows[("reference f64", 16)]["error"]
    # the reference converges onto the truth at second order: halving its step divides the error by
    # about 4 (more where the halved step stops splitting whipping tips)
    assert rows[("reference f64", 8)]["error"] / ref > 3.0
    assert ref < 1e-3 and ref < 0.1 * rows[("DFTL prior s=1 f32", 8)]["error"]
    # DFTL converges (first order, with its numerical damping): the error falls as substeps grow
    assert dftl[0] > dftl[1] > dftl[2]
    # s = 1 keeps lengths to float32 round-off; the prior and posterior forms move alike
    assert rows[("DFTL prior s=1 f32", 8)]["max_stretch"] < 1e-5
    assert rows[("DFTL posterior s=1 f32", 8)]["error"] == pytest.approx(rows[("DFTL prior s=1 f32", 8)]["error"],
                                                                          rel=1e-4)
    # s < 1 does not converge to the truth: further off than s = 1 at the same step; PBD stretches
    assert rows[("DFTL prior s=0.5 f32", 8)]["error"] > 2 * rows[("DFTL prior s=1 f32", 8)]["error"]
    assert rows[("PBD K=4 f32", 8)]["max_stretch"] > 1e-2
    # a groom that never moves is off by the swing itself: more than any solver here
    assert data["result"]["still_error"] > max(dftl)


def test_released_groom_is_the_hanging_groom_turned_45_degrees():
    pts, counts = released_groom(5, 9, 0.2)
    strands = pts.reshape(5, 9, 3)
    seg = np.diff(strands, axis=1)
    assert np.allclose(np.linalg.norm(seg, axis=2), 0.2 / 8)
    d = seg / np.linalg.norm(seg, axis=2, keepdims=True)
    assert np.allclose(d, [np.sin(np.pi / 4), -np.cos(np.pi / 4), 0.0])  # 45 degrees from straight down


def test_pareto_front_on_hand_made_rows():
    rows = [row("a", "dftl", 1.0, 0.5), row("b", "dftl", 2.0, 0.3), row("c", "dftl", 3.0, 0.4),
            row("d", "rattle", 4.0, 0.1), row("e", "pbd", 2.0, 0.6), row("f", "reference", 5.0, 0.1),
            row("g", "dftl", 0.5, float("inf")), row("h", "dftl", 2.0, 0.3)]
    # c is beaten by b, e by b, f by d (same error, dearer), g is not finite; b and h tie: both stay
    assert [rows[i]["label"] for i in pareto_front(rows)] == ["a", "b", "h", "d"]
    assert pareto_front([]) == []


def test_preset_picker_takes_the_cheapest_eligible_setting_under_each_target():
    prior = {"damping": 1.0, "correction": "prior"}
    rows = [
        row("dftl x1", "dftl", 0.1, 0.40, 1, options=prior),
        row("dftl x16", "dftl", 0.3, 0.20, 16, options=prior),
        row("dftl x8 s=0.5", "dftl", 0.2, 0.10, 8, options={"damping": 0.5, "correction": "prior"}),
        row("dftl x256 posterior", "dftl", 1.9, 0.02, 256, options={"damping": 1.0, "correction": "posterior"}),
        row("dftl x256", "dftl", 2.0, 0.02, 256, options=prior),
        row("dftl x512", "dftl", 4.0, 0.01, 512, options=prior),
        row("pbd K=4", "pbd", 1.0, 0.02, 64, stretch=0.05, options={"iterations": 4}),
        row("rattle 2 Newton", "rattle", 8.0, 0.0002, 16, options={"newton_iterations": 2}),
        row("rattle", "rattle", 10.0, 0.0003, 16),
        row("reference", "reference", 20.0, 0.0003, 16, precision="float64"),
    ]
    picks = pick_presets(rows)
    assert set(picks) == set(PRESET_TARGETS)
    assert rows[picks["draft"]["row"]]["label"] == "dftl x16"  # x1 misses 0.25; s=0.5 is not eligible
    assert rows[picks["production"]["row"]]["label"] == "dftl x256"  # posterior and stretching PBD are not
    assert rows[picks["reference"]["row"]]["label"] == "rattle"  # 2 Newton is not a default option
    assert picks["production"]["preset"] == {"solver": "dftl", "damping": 1.0, "correction": "prior",
                                             "substeps": 256, "precision": "float32"}
    assert picks["reference"]["error"] == 0.0003 and picks["reference"]["ms_per_frame"] == 10.0
    assert preset_dict(rows[-1]) == {"solver": "reference", "substeps": 16, "precision": "float64"}
    assert "stretch" in preset_ineligible(rows[6]) and "newton_iterations=2" in preset_ineligible(rows[7])
    # a target nothing meets gives no preset, and the source says so
    none = pick_presets(rows, {"ultra": 1e-6})
    assert none["ultra"]["row"] is None and "no measured setting meets" in presets_source(none)
    source = presets_source(picks)
    namespace = {}
    exec(source, namespace)  # the printed entries are valid Python, ready for quality.py
    assert namespace["QUALITY_PRESETS"]["reference"] == {"solver": "rattle", "substeps": 16, "precision": "float32"}


def test_front_redraws_from_its_json_and_refuses_bad_arguments(smoke, tmp_path, capsys):
    out, data = smoke
    again = tmp_path / "again"
    assert main(["study", "--front-from", str(out / "front.json"), "--out", str(again), "--quiet"]) == 0
    assert json.loads((again / "front.json").read_text())["presets"] == data["presets"]
    assert (again / "front.md").read_text() == (out / "front.md").read_text()
    assert main(["study", "--front", "--strands", "0", "--device", "cpu", "--out", str(tmp_path / "x")]) == 2
    assert "--strands 0" in capsys.readouterr().err
    assert main(["study", "--front-from", str(tmp_path / "missing.json"), "--out", str(tmp_path / "y")]) == 2
