"""Which solver a prim gets when nobody names one: a BasisCurves prim with widths bends like hair of
its thickness (the elastic solver); one without widths, or with ``dftl:bending = false``, is the
plain DFTL chain (``--tolerance`` keeps it elastic too: tests/test_tolerance_elastic.py)."""

from __future__ import annotations

import numpy as np
import pytest
from usd_stages import add_curves, composed_samples, new_stage, set_attr

from dftl_warp import cli
from dftl_warp.simulation.settings import SimulationOptions, group_settings
from dftl_warp.simulation.simulate import simulate_usd
from dftl_warp.usd.read import read_scene

#: 80 um hair, in metres
WIDTH = 80e-6


def _helix(turns=2, radius=0.01, pitch=0.01, per_turn=16):
    t = np.linspace(0.0, 2 * np.pi * turns, turns * per_turn + 1)
    return np.stack([radius * np.cos(t), -pitch * t / (2 * np.pi), radius * np.sin(t)], 1)


def _scene(tmp_path, *, widths=WIDTH, bending=None, hair_hair=False, end=10):
    stage = new_stage(tmp_path / "in.usda", end=end)
    if hair_hair:
        set_attr(stage.GetPrimAtPath("/World"), "dftl:hairHair", "Bool", True)
    h = _helix()
    add_curves(stage, "/World/Hair", h, [len(h)], widths=widths, bending=bending)
    stage.Save()
    return tmp_path / "in.usda"


def _solver(path, **options):
    scene = read_scene(str(path))
    return group_settings(scene, SimulationOptions(**options), 0).solver, scene.warnings


def test_widths_mean_elastic_hair_unless_bending_is_off(tmp_path):
    (tmp_path / "a").mkdir()
    assert _solver(_scene(tmp_path / "a"))[0] == "elastic"
    (tmp_path / "b").mkdir()
    assert _solver(_scene(tmp_path / "b", widths=None))[0] == "dftl"
    (tmp_path / "c").mkdir()
    assert _solver(_scene(tmp_path / "c", bending=False))[0] == "dftl"
    (tmp_path / "d").mkdir()
    solver, warnings = _solver(_scene(tmp_path / "d", widths=0.0))      # zero widths: no hair radius,
    assert solver == "dftl"                                                # and a warning that says so
    assert any("/World/Hair: every width is 0: it runs as a plain DFTL chain" in w for w in warnings), warnings
    assert not _solver(tmp_path / "b" / "in.usda")[1]                      # no widths: nothing to say
    # the command line and dftl:solver still choose
    assert _solver(tmp_path / "a" / "in.usda", solver="pbd")[0] == "pbd"


def test_several_devices_keep_hair_elastic(tmp_path):
    """A groom split across devices bends as on one device (tests/test_multi_device_elastic.py);
    before, it ran as the plain DFTL chain there."""
    solver, warnings = _solver(_scene(tmp_path), device="cpu,cpu")
    assert solver == "elastic"
    assert not any("plain DFTL chain" in w for w in warnings), warnings


def test_hair_hair_keeps_hair_elastic(tmp_path):
    solver, warnings = _solver(_scene(tmp_path, hair_hair=True))
    assert solver == "elastic"
    assert not any("plain DFTL chain" in w for w in warnings), warnings


def test_root_binding_keeps_hair_elastic(tmp_path):
    """Roots bound to a mesh (``dftl:rootMesh``) keep a prim with widths elastic: its clamp turns with
    the bound triangles (tests/test_elastic_binding.py)."""
    from pxr import Sdf, Usd, UsdGeom, Vt

    path = _scene(tmp_path)
    stage = Usd.Stage.Open(str(path))
    scalp = UsdGeom.Mesh.Define(stage, "/World/Scalp")
    scalp.CreateFaceVertexCountsAttr(Vt.IntArray([4]))
    scalp.CreateFaceVertexIndicesAttr(Vt.IntArray([0, 1, 2, 3]))
    quad = np.array([[-0.02, 0, 0.02], [0.02, 0, 0.02], [0.02, 0, -0.02], [-0.02, 0, -0.02]], dtype=np.float32)
    scalp.CreatePointsAttr(Vt.Vec3fArray.FromNumpy(quad))
    stage.GetPrimAtPath("/World/Hair").CreateRelationship("dftl:rootMesh", custom=True).AddTarget(
        Sdf.Path("/World/Scalp"))
    stage.Save()
    solver, warnings = _solver(path)
    assert solver == "elastic"
    assert not any("plain DFTL chain" in w for w in warnings), warnings


def test_a_curl_with_widths_keeps_its_shape_by_default(tmp_path, capsys):
    """The default run of a curl of 80 um hair under gravity: the authored shape is the equilibrium
    (inverse statics), so it stays as authored; the same prim as a DFTL chain (bending off) falls
    straight. info names the solver."""
    path = _scene(tmp_path, end=24)
    out = tmp_path / "out.usdc"
    simulate_usd(path, out)
    x = composed_samples(out, "/World/Hair")[24.0]
    h = _helix()
    length = np.linalg.norm(np.diff(h, axis=0), axis=1).sum()
    assert np.abs(x - h).max() < 1e-3 * length
    (tmp_path / "chain").mkdir()
    chain_path = _scene(tmp_path / "chain", bending=False, end=24)
    simulate_usd(chain_path, tmp_path / "chain.usdc")
    y = composed_samples(tmp_path / "chain.usdc", "/World/Hair")[24.0]
    assert np.abs(y - h).max() > 0.1 * length
    assert cli.main(["info", str(path)]) == 0
    assert "solver elastic" in capsys.readouterr().out


def test_float32_arithmetic_is_a_flag_and_a_styled_curl_still_holds(tmp_path):
    """``--arithmetic float32`` (``arithmetic=`` in the API) runs the elastic solver in float32; the
    provenance records it; the styled curl at rest under gravity (inverse statics) still holds its
    authored shape, now to float32 round-off (1e-5 of its length over 1 s; float64 arithmetic keeps
    it within the 1e-3 bound of the default test above)."""
    from dftl_warp.output import provenance

    path = _scene(tmp_path, end=24)
    out = tmp_path / "out.usdc"
    assert cli.main(["simulate", str(path), "-o", str(out), "--arithmetic", "float32", "--quiet"]) == 0
    x = composed_samples(out, "/World/Hair")[24.0]
    h = _helix()
    length = np.linalg.norm(np.diff(h, axis=0), axis=1).sum()
    assert np.abs(x - h).max() < 1e-5 * length
    assert provenance.read(out)["groups"]["group0"]["arithmetic"] == "float32"


def test_info_counts_the_memory_of_each_prims_solver(tmp_path):
    """``info``'s device memory is what the prims' solvers allocate: an elastic prim (widths) holds its
    rest data, frames, tensions and factorization scratch, several times a DFTL chain's; measured
    against the arrays of the solver built on the whole prim."""
    from dftl_warp.commands.info import ELASTIC_SAMPLE_STRANDS, array_bytes, device_bytes
    from dftl_warp.core.model import Model
    from dftl_warp.solvers import make_solver

    stage = new_stage(tmp_path / "in.usda")
    strands = ELASTIC_SAMPLE_STRANDS + 44  # more than the sample: the estimate is scaled
    h = _helix()
    pts = np.concatenate([h + [0.03 * i, 0.0, 0.0] for i in range(strands)])
    add_curves(stage, "/World/Hair", pts, [len(h)] * strands, widths=WIDTH, bending=None)
    add_curves(stage, "/World/Chain", h + [0.0, 0.0, 0.05], [len(h)])  # no widths: DFTL
    stage.Save()
    scene = read_scene(str(tmp_path / "in.usda"))
    hair, chain = scene.curves
    whole = Model.from_strands(hair.points, hair.counts, device="cpu", precision="float32")
    solver = make_solver(whole, "elastic")
    elastic = array_bytes(whole, solver.state(), whole.control(), solver)
    plain = Model.from_strands(chain.points, chain.counts, device="cpu", precision="float32")
    dftl = make_solver(plain, "dftl")
    dftl_bytes = array_bytes(plain, dftl.state(), plain.control(), dftl)
    assert device_bytes(scene, "float32") == pytest.approx(elastic + dftl_bytes, rel=1e-3)
    assert elastic / hair.num_points > 5 * dftl_bytes / chain.num_points
