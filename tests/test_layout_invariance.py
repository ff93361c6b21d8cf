"""A run does not depend on the particle layout the device keeps (CPU, both layouts).

The CPU keeps strands in input order (strand-major); CUDA keeps each group's strands in the Morton
order of their roots with the state vectors interleaved (particle-major), so every host-side map
from a device strand to a prim, a strand name or a per-strand input goes through the layout's
strand order. One such map did not (the per-prim QC: on the H200 a strand stuck in a sphere was
reported under another prim). Here the same scene -- two DFTL prims in one group, an elastic prim,
a sphere with a strand rooted inside it, drag -- runs on the CPU in both layouts: the written
points, the QC of every prim and every note and warning must agree.
"""

import numpy as np
import pytest
from pxr import Sdf, Usd
from usd_stages import add_curves, chain, composed_samples, new_stage

import dftl_warp.core.layout as layout_module
import dftl_warp.core.model as model_module
from dftl_warp.output.qc import ATTRIBUTES
from dftl_warp.simulation.simulate import simulate_usd

PRIMS = ("/World/Fur", "/World/Hair", "/World/Curls")


def _scene(path):
    from test_usd_features import sphere_collider

    stage = new_stage(path, start=1, end=4)
    d = np.array([1.0, -1.0, 0.0]) / np.sqrt(2)
    fur = [chain(10, 0.01, direction=d, origin=(x, 0.1, z)) for x, z in ((0.0, -0.02), (0.25, 0.0), (0.0, 0.02))]
    add_curves(stage, "/World/Fur", np.concatenate(fur), [10] * 3, widths=0.002)
    held = [chain(10, 0.01, direction=(0.0, 1.0, 0.0), origin=o) for o in ((0.3, 0.3, 0.0), (0.0, 0.05, 0.0))]
    add_curves(stage, "/World/Hair", np.concatenate(held), [10] * 2, widths=0.002)
    t = np.linspace(0.0, 4.0 * np.pi, 12)
    curls = [np.stack([x + 0.004 * np.cos(t), 0.2 - 0.004 * t, 0.004 * np.sin(t)], 1) for x in (-0.2, 0.12, -0.05)]
    add_curves(stage, "/World/Curls", np.concatenate(curls), [12] * 3, widths=1e-4, bending=True)
    sphere_collider(stage, "/World/Ball", 0.1)
    for p in ("/World/Fur", "/World/Hair"):
        stage.GetPrimAtPath(p).CreateAttribute("dftl:drag", Sdf.ValueTypeNames.Float, custom=True).Set(0.5)
    stage.Save()


def _run(tmp_path, name, monkeypatch, cuda_layout):
    if cuda_layout:   # CUDA's choices on the CPU: particle-major, state vectors interleaved
        inter = layout_module.default_interleave
        monkeypatch.setattr(model_module, "default_layout", lambda device: "particle-major")
        monkeypatch.setattr(model_module, "default_interleave",
                            lambda layout, device, *a, **k: inter(layout, "cuda:0", *a, **k))
    out = tmp_path / f"{name}.usdc"
    summary = simulate_usd(tmp_path / "in.usda", out, device="cpu", substeps=4)
    monkeypatch.undo()
    return summary, out


def test_the_same_scene_in_both_layouts_writes_the_same_hair_qc_and_notes(tmp_path, monkeypatch):
    _scene(tmp_path / "in.usda")
    (plain, a), (cuda, b) = (_run(tmp_path, n, monkeypatch, c) for n, c in (("plain", False), ("cuda", True)))
    assert plain.start_notes == cuda.start_notes and plain.warnings == cuda.warnings
    assert any("at /World/Hair strand 1, point 1:" in n for n in plain.start_notes), plain.start_notes
    for prim in PRIMS:
        x, y = composed_samples(a, prim), composed_samples(b, prim)
        assert sorted(x) == sorted(y) == [1.0, 2.0, 3.0, 4.0]
        for t in x:
            assert np.allclose(x[t], y[t], atol=2e-6), (prim, t, np.abs(x[t] - y[t]).max())
    stages = [Usd.Stage.Open(str(p)) for p in (a, b)]
    for prim in PRIMS:
        qc = f"/dftl_qc/{prim.strip('/').replace('/', '_')}"
        for name in ("penetration", "energy", "stretch", "speed"):
            got = [s.GetPrimAtPath(qc).GetAttribute(ATTRIBUTES[name]) for s in stages]
            for t in (1.0, 2.0, 3.0, 4.0):
                assert got[1].Get(t) == pytest.approx(got[0].Get(t), rel=1e-4, abs=1e-6), (prim, name, t)
    hair = stages[0].GetPrimAtPath("/dftl_qc/World_Hair").GetAttribute(ATTRIBUTES["penetration"]).Get(1.0)
    assert hair > 10.0   # the strand rooted inside the sphere is measured under its own prim
