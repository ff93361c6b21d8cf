"""The elastic solver from USD and the CLI (CPU): a bound curve-deformable material in stage units,
the cantilever against the elastica, centimetres = metres, a rotating clamp, a stiffness ramp,
``info``'s material and bending length, one-line errors, and checkpoints."""

from __future__ import annotations

import numpy as np
import pytest
from pxr import Sdf, Usd, UsdGeom, UsdPhysics, UsdShade, Vt

from dftl_warp import cli
from test_elastic import LB, elastica

N = 32
WIDTH = 80e-6


def stage(path, mpu=1.0, ratios=(0.5, 2.0), end=97, material=True, extra=None, scale=None, parent=None,
          inverse_statics=False, drag=20.0):
    """Horizontal cantilevers of 80 um hair, L = ratios x l_b, N segments, in a stage of ``mpu``."""
    st = Usd.Stage.CreateNew(str(path))
    UsdGeom.SetStageMetersPerUnit(st, mpu)
    UsdGeom.SetStageUpAxis(st, "Y")
    st.SetStartTimeCode(1)
    st.SetEndTimeCode(end)
    hair_path = "/Hair" if parent is None else "/Rig/Hair"
    if parent is not None:
        xf = UsdGeom.Xform.Define(st, "/Rig")
        op = xf.AddRotateYOp()
        for frame, angle in parent:
            op.Set(angle, frame)
    c = UsdGeom.BasisCurves.Define(st, hair_path)
    c.CreateTypeAttr("linear")
    pts = []
    for k, r in enumerate(ratios):
        p = np.zeros((N + 1, 3))
        p[:, 0] = np.linspace(0, r * LB, N + 1) + (0.01 if parent is not None else 0.0)
        p[:, 2] = 0.02 * k
        pts.append(p / mpu)
    c.CreatePointsAttr(Vt.Vec3fArray.FromNumpy(np.concatenate(pts).astype(np.float32)))
    c.CreateCurveVertexCountsAttr([N + 1] * len(ratios))
    c.CreateWidthsAttr([WIDTH / mpu])
    c.SetWidthsInterpolation("constant")
    prim = c.GetPrim()
    prim.CreateAttribute("dftl:solver", Sdf.ValueTypeNames.Token).Set("elastic")
    prim.CreateAttribute("dftl:inverseStatics", Sdf.ValueTypeNames.Bool).Set(inverse_statics)
    prim.CreateAttribute("dftl:drag", Sdf.ValueTypeNames.Float).Set(drag)
    if scale is not None:
        pv = UsdGeom.PrimvarsAPI(prim).CreatePrimvar("dftl:bendStiffnessScale", Sdf.ValueTypeNames.FloatArray,
                                                     UsdGeom.Tokens.uniform)
        pv.Set(scale)
    if material:
        m = UsdShade.Material.Define(st, "/Looks/HairPhysics")
        m.GetPrim().AddAppliedSchema("PhysicsCurvesDeformableMaterialAPI")
        UsdPhysics.MaterialAPI.Apply(m.GetPrim())
        attrs = {"physics:youngsModulus": 3.89e9 * mpu, "physics:density": 1320.0 * mpu ** 3, **(extra or {})}
        for name, value in attrs.items():
            m.GetPrim().CreateAttribute(name, Sdf.ValueTypeNames.Float).Set(value)
        UsdShade.MaterialBindingAPI.Apply(prim).Bind(m, materialPurpose="physics")
    st.Save()
    return hair_path


def simulate(tmp_path, src, *flags):
    out = tmp_path / (src.stem + "_out.usdc")
    code = cli.main(["simulate", str(src), "-o", str(out), "--device", "cpu", "--quiet", *flags])
    assert code == 0
    return out


def last_points(out, hair_path, ratios):
    st = Usd.Stage.Open(str(out))
    curves = UsdGeom.BasisCurves(st.GetPrimAtPath(hair_path))
    frame = st.GetEndTimeCode()
    p = np.array(curves.GetPointsAttr().Get(frame), dtype=np.float64)
    return p.reshape(len(ratios), N + 1, 3) * UsdGeom.GetStageMetersPerUnit(st)


def elastica_error(L, x, stretch=1.0):
    """Max distance / L of ``x`` from the elastica of length L (of a hair whose E*I is
    ``stretch^3`` times hair's: the elastica of L / stretch, scaled by ``stretch``)."""
    s = np.linspace(0, L / stretch, N + 1)
    xe, ye = elastica(L / stretch, s)
    return np.linalg.norm(np.c_[xe, ye] * stretch - (x[:, :2] - x[:1, :2]), axis=1).max() / L


@pytest.fixture(scope="module")
def cantilevers(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("cantilever")
    out = {}
    for mpu in (1.0, 0.01):
        src = tmp / f"cantilever_{mpu:g}.usda"
        stage(src, mpu)
        out[mpu] = last_points(simulate(tmp, src, "--solver", "elastic"), "/Hair", (0.5, 2.0))
    return out


@pytest.mark.parametrize("k,ratio", [(0, 0.5), (1, 2.0)])
def test_cantilever_from_a_bound_material_matches_the_elastica(cantilevers, k, ratio):
    assert elastica_error(ratio * LB, cantilevers[1.0][k]) < 0.02


def test_centimetre_stage_sags_like_a_metre_stage(cantilevers):
    for k, ratio in enumerate((0.5, 2.0)):
        assert np.abs(cantilevers[0.01][k] - cantilevers[1.0][k]).max() < 1e-3 * ratio * LB


def test_bend_stiffness_scale_ramp(tmp_path):
    """primvars:dftl:bendStiffnessScale = 8 doubles the bending length: a 2 l_b strand sags as the
    l_b elastica, twice as large; physics:curvesBendStiffness (E*I) overrides E the same way."""
    src = tmp_path / "ramp.usda"
    stage(src, 1.0, ratios=(2.0, 2.0), scale=[8.0, 1.0])
    x = last_points(simulate(tmp_path, src), "/Hair", (2.0, 2.0))
    assert elastica_error(2 * LB, x[0], stretch=2.0) < 0.02
    assert elastica_error(2 * LB, x[1]) < 0.02
    src = tmp_path / "ei.usda"
    EI = 3.89e9 * np.pi * (WIDTH / 2) ** 4 / 4
    stage(src, 0.01, ratios=(2.0,), extra={"physics:curvesBendStiffness": 8 * EI / 0.01 ** 3})
    x = last_points(simulate(tmp_path, src), "/Hair", (2.0,))
    assert elastica_error(2 * LB, x[0], stretch=2.0) < 0.02


def test_rotating_parent_turns_the_clamp(tmp_path):
    """The parent turns 90 degrees about +y over a second: the short stiff strand leaves its root
    along the turned direction and ends near the turned rest tip."""
    src = tmp_path / "turn.usda"
    hair = stage(src, 1.0, ratios=(0.5,), end=49, parent=[(1, 0.0), (25, 90.0)], inverse_statics=True)
    out = simulate(tmp_path, src)
    st = Usd.Stage.Open(str(out))
    curves = UsdGeom.BasisCurves(st.GetPrimAtPath(hair))
    local = np.array(curves.GetPointsAttr().Get(49), dtype=np.float64)
    world = local @ np.array(UsdGeom.Xformable(curves).ComputeLocalToWorldTransform(49))[:3, :3]
    L = 0.5 * LB
    rest_tip = np.array([0.01 + L, 0.0, 0.0])
    turned = np.array([0.0, 0.0, -(0.01 + L)])     # rotateY(90): x -> -z
    assert np.linalg.norm(world[-1] - turned) < 0.01 * L
    assert np.linalg.norm(local[-1] - rest_tip) < 0.01 * L


def test_info_prints_material_and_bending_length(tmp_path, capsys):
    src = tmp_path / "info.usda"
    stage(src, 0.01, ratios=(1.0,))
    assert cli.main(["info", str(src)]) == 0
    text = capsys.readouterr().out
    assert "from bound material /Looks/HairPhysics" in text
    line = next(l for l in text.splitlines() if "bending length" in l)
    units, metres = float(line.split()[2]), float(line.split()[5])
    assert abs(units * 0.01 - LB) < 1e-3 * LB and abs(metres - LB) < 1e-3 * LB
    src = tmp_path / "plain.usda"
    stage(src, 1.0, ratios=(1.0,), material=False)
    assert cli.main(["info", str(src)]) == 0
    assert "from defaults (human hair" in capsys.readouterr().out


@pytest.mark.parametrize("extra,message", [
    ({"physics:youngsModulu": 1e9}, "unknown attribute physics:youngsModulu (did you mean physics:youngsModulus?)"),
    ({"physics:density": -1.0}, "physics:density = -1: must be a finite number > 0"),
    ({"physics:poissonsRatio": 0.7}, "physics:poissonsRatio = 0.7: must be a finite number in (-1, 0.5]"),
])
def test_bad_material_is_one_line_and_exit_2(tmp_path, capfd, extra, message):
    src = tmp_path / "bad.usda"
    stage(src, 1.0, ratios=(1.0,), extra=extra)
    code = cli.main(["simulate", str(src), "-o", str(tmp_path / "o.usdc"), "--device", "cpu", "--quiet"])
    err = capfd.readouterr().err.strip()
    assert code == 2
    assert len(err.splitlines()) == 1 and message in err, err
    assert not (tmp_path / "o.usdc").exists()


def test_checkpoint_carries_the_elastic_state(tmp_path):
    from resume_check import assert_resumes_exactly

    from dftl_warp.simulation.settings import SimulationOptions
    from dftl_warp.usd.read import read_scene

    src = tmp_path / "ckpt.usda"
    stage(src, 1.0, ratios=(1.0,), end=30, parent=[(1, 0.0), (30, 60.0)], drag=0.0)
    assert_resumes_exactly(read_scene(str(src)), SimulationOptions(device="cpu", precision="float64"), 6, 6,
                           keys=("group0.tensions", "group0.frames", "group0.clamps"))


def test_several_devices_write_the_single_device_file(tmp_path):
    """Two cantilevers on a turning rig split over two devices: the clamps turn per part, and the
    written points are those of one device (before, several devices were refused)."""
    src = tmp_path / "split.usda"
    stage(src, 1.0, ratios=(1.0, 0.5), end=6, parent=[(1, 0.0), (6, 40.0)])
    points = {}
    for device in ("cpu", "cpu,cpu"):
        out = tmp_path / f"{device.replace(',', '_')}.usdc"
        assert cli.main(["simulate", str(src), "-o", str(out), "--device", device, "--quiet"]) == 0
        written = Usd.Stage.Open(str(out))
        attr = written.GetPrimAtPath("/Rig/Hair").GetAttribute("points")
        points[device] = [np.asarray(attr.Get(t)) for t in range(1, 7)]
    assert np.abs(points["cpu"][-1] - points["cpu"][0]).max() > 1e-3    # the rig turned the hair
    for a, b in zip(points["cpu"], points["cpu,cpu"]):
        assert a.tobytes() == b.tobytes()
