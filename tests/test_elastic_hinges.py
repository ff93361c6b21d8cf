"""A bending stiffness scale of 0 (``stiffness_scale`` in the API, ``primvars:dftl:bendStiffnessScale``
in USD) is a hinge: no bending at that vertex. The solver builds it without numpy's divide/invalid
warnings (inverse statics divided by the stiffness), a strand of zeros hangs like the plain DFTL
chain, a hinge in the middle of a held-out strand lets its outer half hang, ``simulate`` says where
the authored shape cannot be held, and negative or NaN scales are refused naming the index (CPU)."""

from __future__ import annotations

import contextlib
import re
import warnings

import numpy as np
import pytest
from pxr import Sdf, UsdGeom

import dftl_warp as dw
from dftl_warp import cli
from dftl_warp.solvers.elastic import HAIR_DENSITY, HAIR_E, TWIST_G
from dftl_warp.solvers.elastic_rest import RodGroup
from dftl_warp.solvers.elastic_stability import holding_scales, stiffness_margins

R, N, L = 40e-6, 16, 0.05


def strand(direction=(1.0, 0.0, 0.0), n=N, length=L):
    return np.outer(np.linspace(0.0, length, n + 1), direction)


@contextlib.contextmanager
def strict():
    """numpy's floating-point warnings (and any RuntimeWarning) become errors."""
    with warnings.catch_warnings(), np.errstate(all="raise"):
        warnings.simplefilter("error", RuntimeWarning)
        yield


def settle(model, solver, frames=48):
    state, control = solver.state(), model.control()
    for _ in range(frames):
        solver.advance(state, control, 1.0 / 24, 8)
    return model.points_from_device(state.positions)


@pytest.fixture(scope="module")
def horizontal():
    return dw.Model.from_strands(strand(), [N + 1], widths=2 * R, device="cpu", precision="float64")


def test_zero_scales_hang_like_the_plain_chain_without_numpy_warnings(horizontal):
    m = horizontal
    with strict():
        held = settle(m, dw.make_solver(m, "elastic", drag=5.0))
        zero = dw.make_solver(m, "elastic", stiffness_scale=0.0, drag=5.0)
        limp = settle(m, zero)
        mid = dw.make_solver(m, "elastic", stiffness_scale=np.where(np.arange(N + 1) == N // 2, 0.0, 1.0), drag=5.0)
        halves = settle(m, mid)
    chain = settle(m, dw.make_solver(m, "dftl"))
    for p in (held, limp, halves):
        assert np.isfinite(p).all()
    # stiffness 1: inverse statics holds the authored horizontal strand
    assert np.abs(held - strand()).max() < 1e-3 * L
    # every scale 0: no bending anywhere, the strand hangs straight down as the DFTL chain does
    assert np.abs(limp - chain).max() < 1e-3 * L
    assert abs(limp[-1, 1] + L) < 1e-3 * L
    # a hinge at the middle vertex: the inner half stays out, the outer half hangs from the hinge
    assert np.abs(halves[:N // 2 + 1] - strand()[:N // 2 + 1]).max() < 0.05 * L
    hanging = halves[N // 2:] - halves[N // 2]
    assert abs(hanging[-1, 1] + L / 2) < 0.02 * L and abs(hanging[-1, 0]) < 0.02 * L
    # what the solver reports: the vertices whose moment the authored shape needs
    assert zero.unheld_vertices()[0].tolist() == [0] and zero.unheld_vertices()[1] == N
    assert mid.unheld_vertices()[0].tolist() == [0] and mid.unheld_vertices()[1] == 1


def test_a_hanging_strand_needs_no_moment_at_its_hinges():
    m = dw.Model.from_strands(strand((0.0, -1.0, 0.0)), [N + 1], widths=2 * R, device="cpu", precision="float64")
    with strict():
        solver = dw.make_solver(m, "elastic", stiffness_scale=np.r_[np.ones(8), np.zeros(N - 7)])
        assert solver.unheld_vertices()[1] == 0
        flagged, _, tested, total = solver.unstable_strands()
        assert flagged.size == 0 and tested == total == 1
        p = settle(m, solver, frames=6)
    assert np.abs(p - strand((0.0, -1.0, 0.0))).max() < 1e-6 * L


def test_stability_test_with_hinges_is_finite():
    """A column of hair standing on a hinge falls whatever the stiffness of the rest: the margin is
    negative and no scale holds it (inf); a hanging chain without bending is stable."""
    def group(points, scale):
        return RodGroup(points[None], np.full((1, len(points)), R), E=HAIR_E, G=TWIST_G, rho=HAIR_DENSITY,
                        gravity=(0.0, -9.81, 0.0), inverse_statics=True, bend_scale=np.asarray(scale)[None])

    with strict():
        up = strand((0.0, 1.0, 0.0), length=0.02)
        standing = group(up, np.where(np.arange(N + 1) == 4, 0.0, 1.0))
        assert not standing.unheld.any()        # a straight column needs no moment to stand
        assert stiffness_margins(standing)[0] < 0
        assert holding_scales(standing).tolist() == [np.inf]
        assert holding_scales(group(up, np.ones(N + 1)))[0] < 1.0   # without the hinge its stiffness holds it
        limp = group(strand((0.0, -1.0, 0.0)), np.zeros(N + 1))
        assert 0 < stiffness_margins(limp)[0] < np.inf


@pytest.mark.parametrize("bad, shown", [(-1.0, "-1.0"), (float("nan"), "nan")])
def test_negative_or_nan_scale_is_refused_naming_the_index(horizontal, bad, shown):
    scale = np.ones(N + 1)
    scale[3] = bad
    with pytest.raises(ValueError, match=rf"stiffness_scale\[3\] = {shown}: must be finite and >= 0"):
        dw.make_solver(horizontal, "elastic", stiffness_scale=scale)


def scaled_stage(path, scale):
    from usd_stages import add_curves, new_stage

    stage = new_stage(path, start=1, end=4)
    curves = add_curves(stage, "/World/Hair", strand(), [N + 1], widths=2 * R, bending=None)
    pv = UsdGeom.PrimvarsAPI(curves.GetPrim()).CreatePrimvar("dftl:bendStiffnessScale", Sdf.ValueTypeNames.FloatArray,
                                                             UsdGeom.Tokens.vertex)
    pv.Set([float(s) for s in scale])
    stage.Save()
    return path


def test_simulate_says_where_a_hinge_cannot_hold_the_shape(tmp_path, capsys):
    scale = np.ones(N + 1)
    scale[[5, 9]] = 0.0
    src = scaled_stage(tmp_path / "hinge.usda", scale)
    out = tmp_path / "out.usdc"
    assert cli.main(["simulate", str(src), "-o", str(out), "--device", "cpu"]) == 0
    err = capsys.readouterr().err
    assert "RuntimeWarning" not in err and "Traceback" not in err, err
    notes = [line for line in err.splitlines() if "bendStiffnessScale 0" in line]
    assert len(notes) == 1 and "/World/Hair: 2 vertices of 1 strand have primvars:dftl:bendStiffnessScale 0" \
        in notes[0] and "inverse statics cannot hold it" in notes[0], err
    from pxr import Usd

    result = Usd.Stage.Open(str(out))
    p = np.array(UsdGeom.BasisCurves(result.GetPrimAtPath("/World/Hair")).GetPointsAttr().Get(4))
    assert np.isfinite(p).all() and p[-1, 1] < -0.1 * L      # the outer part has started to hang


@pytest.mark.parametrize("bad, message", [(-0.5, r"primvars:dftl:bendStiffnessScale\[7\] is negative"),
                                          (float("nan"), r"primvars:dftl:bendStiffnessScale\[7\] is not finite")])
def test_negative_or_nan_primvar_is_one_line_naming_file_prim_and_index(tmp_path, capsys, bad, message):
    scale = np.ones(N + 1)
    scale[7] = bad
    src = scaled_stage(tmp_path / "bad.usda", scale)
    out = tmp_path / "out.usdc"
    assert cli.main(["simulate", str(src), "-o", str(out), "--device", "cpu", "--quiet"]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and str(src) in lines[0] and "/World/Hair" in lines[0], lines
    assert re.search(message, lines[0]), lines[0]
    assert not out.exists()
