"""``info --guides N`` describes what ``simulate --guides N`` simulates: the guides it picks.

Before, ``info`` took no ``--guides`` and its hair-hair statistics (rest volume fraction, densest
node, grid), features and memory were those of every strand, while ``simulate --guides`` builds
its grid over the guides only (a tenth of the hair: a tenth of the volume fraction). Now
``info --guides`` picks the guides as simulate does and says which strands the figures describe.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from pxr import Sdf
from usd_stages import add_curves, chain, new_stage

from dftl_warp import cli
from dftl_warp import features as F
from dftl_warp.features.hair_hair import group_rest_statistics
from dftl_warp.guides import select_guides

STRANDS, VERTICES = 20, 10


def hair_hair_stage(path):
    stage = new_stage(path, start=1, end=4, meters_per_unit=0.01)
    pts = np.concatenate([chain(VERTICES, 1.0, direction=(0, -1, 0), origin=(0.2 * k, 0, 0)) for k in range(STRANDS)])
    add_curves(stage, "/World/Hair", pts, [VERTICES] * STRANDS, widths=0.008)
    stage.GetPrimAtPath("/World").CreateAttribute("dftl:hairHair", Sdf.ValueTypeNames.Bool, custom=True).Set(True)
    stage.Save()
    return pts


def info_json(capsys, *argv) -> dict:
    assert cli.main(["info", *map(str, argv), "--json"]) == 0
    return json.loads(capsys.readouterr().out)


def test_info_guides_describes_the_guides_simulate_runs(tmp_path, capsys):
    path = tmp_path / "hh.usda"
    pts = hair_hair_stage(path)
    counts = np.full(STRANDS, VERTICES)
    full = info_json(capsys, path)
    five = info_json(capsys, path, "--guides", "5")
    assert full["simulated_strands"] == STRANDS and full["guides"] is None
    assert five["strands"] == STRANDS and five["simulated_strands"] == 5
    assert five["curves"][0]["simulated_strands"] == 5
    assert five["guides"] == {"method": "kmeans", "count": 5, "render_strands": STRANDS}
    # the grid is splatted from the guides simulate picks (its own selection, at the first frame)
    guides = np.asarray(select_guides(pts, counts, 5, "kmeans"))
    gpts = pts.reshape(STRANDS, VERTICES, 3)[guides].reshape(-1, 3)
    want, peak = group_rest_statistics(F.HairHair(cell_size=4.0, hair_width=0.008), gpts, [VERTICES] * 5, 0.008)
    (hh,) = five["hair_hair"]
    assert hh["rest_volume_fraction"] == pytest.approx(want, rel=1e-5)
    assert hh["rest_peak"] == pytest.approx(peak, rel=1e-5)
    # a quarter of the strands in the same cells: about a quarter of the hair's volume fraction
    ratio = hh["rest_volume_fraction"] / full["hair_hair"][0]["rest_volume_fraction"]
    assert 0.15 < ratio < 0.4, ratio
    assert five["device_bytes"]["float32"] < full["device_bytes"]["float32"]


def test_info_says_which_strands_its_figures_describe(tmp_path, capsys):
    path = tmp_path / "hh.usda"
    hair_hair_stage(path)
    assert cli.main(["info", str(path), "--guides", "25%"]) == 0
    out = capsys.readouterr().out
    assert ("guides      --guides 25% (kmeans): 5 of 20 strands simulated, 20 render strands deformed from them; "
            "the features, hair-hair and memory below are the simulated guides'") in out, out
    assert "solver dftl on 5 of its strands (guides), the rest deformed from them" in out or \
           "on 5 of its strands (guides)" in out, out


def test_info_guide_method_without_guides_warns_and_bad_guides_are_one_line(tmp_path, capsys):
    path = tmp_path / "hh.usda"
    hair_hair_stage(path)
    assert cli.main(["info", str(path), "--guide-method", "fps"]) == 0
    assert "--guide-method fps does nothing without --guides: ignored" in capsys.readouterr().out
    assert cli.main(["info", str(path), "--guides", "50"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"dftl-warp: error: {path}: /World/Hair: --guides 50"), err
