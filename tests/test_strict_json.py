"""The --json outputs are strict JSON: a value that is not finite is null (Python's json wrote NaN
and Infinity, which strict readers such as JavaScript's JSON.parse refuse)."""

import json
import math

import numpy as np
from usd_stages import add_curves, chain, new_stage

from dftl_warp import cli
from dftl_warp.commands import info, strict_json


def refuse(constant):
    raise ValueError(f"not strict JSON: {constant}")


def test_values_that_are_not_finite_are_null_at_any_depth():
    text = strict_json.dumps({"a": math.nan, "b": [1.0, math.inf, (2.0, -math.inf)], "c": {"d": 3}})
    assert json.loads(text, parse_constant=refuse) == {"a": None, "b": [1.0, None, [2.0, None]], "c": {"d": 3}}


def test_info_json_is_strict_even_with_a_value_that_is_not_finite(tmp_path, capsys, monkeypatch):
    stage = new_stage(tmp_path / "in.usda", start=1, end=2)
    add_curves(stage, "/World/Hair", chain(4, 0.01, direction=(0, -1, 0)), [4])
    stage.Save()
    describe = info.describe
    monkeypatch.setattr(info, "describe", lambda scene, *a, **k: dict(describe(scene, *a, **k), probe=float("nan")))
    assert cli.main(["info", "--json", str(tmp_path / "in.usda")]) == 0
    d = json.loads(capsys.readouterr().out, parse_constant=refuse)
    assert d["probe"] is None and np.isfinite(d["strands"])
