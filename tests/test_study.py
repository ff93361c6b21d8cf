"""`dftl-warp study --fast`: the CI subset of the accuracy study, end to end."""

import csv
import json
from pathlib import Path

import pytest

from dftl_warp.cli import main
from dftl_warp.simulation.quality import QUALITY_MEASURED, QUALITY_PRESETS, quality_preset
from dftl_warp.study.front import PRESET_TARGETS


def read(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def test_study_fast_writes_tables_plots_and_report(tmp_path, capsys):
    out, docs = tmp_path / "study", tmp_path / "docs" / "accuracy.md"
    assert main(["study", "--fast", "--out", str(out), "--docs", str(docs)]) == 0
    for name in ("convergence", "energy", "groom", "stretch", "modes", "stability"):
        assert (out / f"{name}.csv").stat().st_size > 0
    for name in ("convergence", "pareto", "energy", "stretch", "modes", "stability"):
        assert (out / f"{name}.png").read_bytes()[:4] == b"\x89PNG"
    report = docs.read_text()
    assert "![error against dt](../study/convergence.png)" in report
    assert "dftl-warp study --fast --out" in report  # the command that made it is recorded
    assert "(fast subset)" in report

    conv = read(out / "convergence.csv")
    def errors(setting):
        return [float(r["error"]) for r in conv if r["setting"] == setting]
    s1, s08 = errors("dftl s=1 prior f64"), errors("dftl s=0.8 f64")
    assert s1[0] > 1.7 * s1[1] > 1.7**2 * s1[2]  # first order: each halving about halves it
    assert s08[-1] > 0.8 * s08[0] and s08[-1] > 10 * s1[-1]  # s < 1 stalls
    assert errors("dftl s=1 posterior f64") == pytest.approx(s1, rel=1e-6)

    groom = {(r["setting"], int(r["substeps"])): r for r in read(out / "groom.csv")}
    assert float(groom[("pbd K=4 f32", 1)]["max_stretch"]) > 0.1  # PBD stretches
    assert float(groom[("dftl s=1 f32", 1)]["max_stretch"]) < 1e-5  # DFTL does not
    assert float(groom[("reference f64", 8)]["max_stretch"]) < 1e-12
    assert {"preset draft", "preset production", "preset reference"} <= {k[0] for k in groom}

    modes = {r["setting"]: r for r in read(out / "modes.csv")}
    assert abs(float(modes["reference"]["period_error"])) < 1e-3
    assert float(modes["reference"]["amplitude_per_period"]) > 0.99
    assert float(modes["dftl s=1"]["amplitude_per_period"]) < 0.95  # DFTL damps

    stab = {(float(r["damping"]), int(r["particles"]), float(r["dt"])): r["unstable"] == "True"
            for r in read(out / "stability.csv")}
    assert not any(v for (s, _, _), v in stab.items() if s == 1.0)
    assert [v for (s, n, dt), v in stab.items() if s == 0.5 and n == 64 and abs(dt / 1e-4 - 1) < 0.01] == [True]

    # elastic strands: the elastic solver against the reference with the same elastic energy
    assert (out / "elastic.png").read_bytes()[:4] == b"\x89PNG"
    assert "Elastic strands: the elastic solver against the elastic reference" in report
    refs = {r["scenario"]: r for r in read(out / "elastic_reference.csv")}
    assert set(refs) == {"cantilever", "curly"}
    elastic = {(r["scenario"], r["setting"], int(r["substeps"])): r for r in read(out / "elastic.csv")}
    e8, e32 = (float(elastic[("cantilever", "elastic s=1 (default)", k)]["error"]) for k in (8, 32))
    assert e8 > 2.0 * e32  # first order: 4x the substeps, about a quarter of the error
    assert float(refs["cantilever"]["self_error"]) < 1e-3 * e32  # the reference is far more accurate
    assert all(float(r["max_stretch"]) < 1e-10 for r in elastic.values())  # both are inextensible


def test_study_refuses_an_unknown_device(tmp_path, capsys):
    assert main(["study", "--fast", "--device", "cuda:7", "--out", str(tmp_path / "x")]) == 2
    err = capsys.readouterr().err
    assert err.startswith("dftl-warp: error: --device cuda:7") and "Traceback" not in err
    assert not (tmp_path / "x").exists()


def test_quality_presets_are_documented_combinations():
    assert set(QUALITY_PRESETS) == {"draft", "production", "reference"}
    for name, preset in QUALITY_PRESETS.items():
        assert {"solver", "substeps", "precision"} <= set(preset)
    # each preset is the front's pick, with the error and cost the front measured (H200 run in docs)
    front = json.loads((Path(__file__).parents[1] / "docs" / "accuracy-h200" / "front.json").read_text())
    for name, pick in front["presets"].items():
        assert quality_preset(name) == pick["preset"]
        assert pick["error"] <= PRESET_TARGETS[name]
        error, ms = QUALITY_MEASURED[name]
        assert error == pytest.approx(pick["error"], rel=0.01) and ms == pytest.approx(pick["ms_per_frame"], rel=0.01)
    with pytest.raises(ValueError, match="unknown quality"):
        quality_preset("ultra")
