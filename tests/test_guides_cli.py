"""Guides and render prims through the command line (issue 22, docs/guides.md): ``rel dftl:guides``,
``simulate --guides``, ``--guides-output binding`` and the input errors."""

import shutil
from pathlib import Path

import numpy as np
import pytest
from pxr import Gf, Sdf, Usd, UsdGeom, UsdPhysics
from usd_stages import add_curves, animated_xform, composed_samples, local_to_world, new_stage, set_attr

from dftl_warp import cli
from dftl_warp.guides import bind, deform_reference
from dftl_warp.guides.binding import pin_roots
from dftl_warp.usd.scene import transform_points

N = 8  # vertices per strand
FRAMES = 6


def strands(angles, radius=0.1, length=0.2, curl=0.0):
    """Strands rooted on a circle of ``radius`` in the XZ plane, going out and down, N vertices."""
    pts = []
    for a in angles:
        out = np.array([np.cos(a), 0.0, np.sin(a)])
        side = np.array([-np.sin(a), 0.0, np.cos(a)])
        for i in range(N):
            s = i / (N - 1)
            p = radius * out + length * s * (0.6 * out + np.array([0.0, -0.8, 0.0]))
            p = p + curl * s * np.sin(3 * np.pi * s) * side
            pts.append(p)
    return np.array(pts), [N] * len(angles)


GUIDE_ANGLES = np.linspace(0, 2 * np.pi, 8, endpoint=False)
RENDER_ANGLES = np.linspace(0.1, 2 * np.pi + 0.1, 40, endpoint=False)


def groom_stage(path, *, turn=None, static_turn=0.0, guides_rel=True, render_under=None):
    """/World/Head (turning about Y over the frames with ``turn``, else turned ``static_turn`` deg),
    guides /World/Head/Guides, render curves /World/Head/Offset/Hair (an extra static transform)."""
    stage = new_stage(path, start=1, end=FRAMES)
    if turn:
        animated_xform(stage, "/World/Head", rotate_y={1: 0.0, FRAMES: turn})
    else:
        xf = UsdGeom.Xform.Define(stage, "/World/Head")
        xf.AddRotateYOp().Set(float(static_turn))
    off = UsdGeom.Xform.Define(stage, "/World/Head/Offset")
    off.AddTranslateOp().Set(Gf.Vec3d(0.0, 0.0, 0.0))
    off.AddRotateYOp().Set(25.0)
    gp, gc = strands(GUIDE_ANGLES)
    add_curves(stage, "/World/Head/Guides", gp, gc)
    rp, rc = strands(RENDER_ANGLES, radius=0.105, curl=0.01)
    # the render prim's local points: the world rest points through the inverse of Offset's rotation
    inv = np.linalg.inv(np.array(off.GetLocalTransformation(), dtype=np.float64))
    add_curves(stage, "/World/Head/Offset/Hair", transform_points(inv, rp), rc)
    if guides_rel:
        stage.GetPrimAtPath("/World/Head/Offset/Hair").CreateRelationship("dftl:guides").SetTargets(
            [Sdf.Path("/World/Head/Guides")])
    stage.Save()
    return stage


def dense_stage(tmp_path):
    """(path, points) of a stage of 40 curled strands on a static head, frames 1..4."""
    src = tmp_path / "dense.usda"
    stage = new_stage(src, start=1, end=4)
    rp, rc = strands(RENDER_ANGLES, curl=0.01)
    add_curves(stage, "/World/Hair", rp, rc)
    stage.Save()
    return src, rp


def run(argv, capsys=None):
    code = cli.main(["simulate", *map(str, argv), "--device", "cpu", "--quiet"])
    return code


def test_render_prim_follows_its_guides_and_guides_equal_a_plain_simulation(tmp_path, capsys):
    src = tmp_path / "groom.usda"
    groom_stage(src, turn=80.0)
    out = tmp_path / "out.usdc"
    assert run([src, "-o", out]) == 0
    line = capsys.readouterr().out
    assert f" 8 strands, {8 * N} particles" in line  # only the guides are simulated
    render = composed_samples(out, "/World/Head/Offset/Hair")
    guides = composed_samples(out, "/World/Head/Guides")
    assert sorted(render) == [float(f) for f in range(1, FRAMES + 1)]
    assert render[1.0].shape == (40 * N, 3)

    # the guides: exactly a plain simulation of the guides alone
    plain = tmp_path / "plain.usda"
    shutil.copy(src, plain)
    stage = Usd.Stage.Open(str(plain))
    stage.RemovePrim("/World/Head/Offset/Hair")
    stage.Save()
    out2 = tmp_path / "plain.usdc"
    assert run([plain, "-o", out2]) == 0
    alone = composed_samples(out2, "/World/Head/Guides")
    for t in alone:
        np.testing.assert_array_equal(guides[t], alone[t])
    assert np.abs(guides[float(FRAMES)] - guides[1.0]).max() > 1e-3  # the guides did move

    # the render strands follow the rigid turn of the head exactly: bound in the head's frame, the
    # reference deformation of the guides' (head-local) output, each strand's root pinned where the
    # head holds it (pin_roots), is the render prim's output there
    head = {t: local_to_world(src, "/World/Head", t) for t in render}
    hair = {t: local_to_world(src, "/World/Head/Offset/Hair", t) for t in render}
    inp = Usd.Stage.Open(str(src))
    r0 = np.array(inp.GetPrimAtPath("/World/Head/Offset/Hair").GetAttribute("points").Get(), dtype=np.float64)
    g0 = np.array(inp.GetPrimAtPath("/World/Head/Guides").GetAttribute("points").Get(), dtype=np.float64)
    rest_r = transform_points(hair[1.0] @ np.linalg.inv(head[1.0]), r0)
    b = bind(g0, [N] * 8, rest_r, [N] * 40, k=4)
    for t in render:
        expected_head = pin_roots(deform_reference(b, guides[t]), b, rest_r[::N])   # guides' space: the head's
        got_head = transform_points(hair[t] @ np.linalg.inv(head[t]), render[t])
        np.testing.assert_allclose(got_head, expected_head, atol=2e-6)
    np.testing.assert_allclose(render[1.0], r0, atol=2e-6)

    # velocities: the backward difference of the deformed local points, zero at the first frame
    vel = composed_samples(out, "/World/Head/Offset/Hair", "velocities")
    assert np.all(vel[1.0] == 0)
    for t in list(render)[1:]:
        np.testing.assert_allclose(vel[t], (render[t] - render[t - 1]) * 24.0, atol=2e-3)


def test_guides_fraction_on_a_dense_groom(tmp_path, capsys):
    src, rp = dense_stage(tmp_path)
    out = tmp_path / "out.usdc"
    assert run([src, "-o", out, "--guides", "10%", "--guide-method", "fps"]) == 0
    assert f" 4 strands, {4 * N} particles" in capsys.readouterr().out
    got = composed_samples(out, "/World/Hair")
    assert sorted(got) == [1.0, 2.0, 3.0, 4.0] and got[4.0].shape == (40 * N, 3)
    tips = (got[4.0] - got[1.0]).reshape(40, N, 3)[:, -1]
    assert np.linalg.norm(tips, axis=1).min() > 1e-3  # every strand moved
    np.testing.assert_allclose(got[1.0], rp, atol=2e-6)
    assert run([src, "-o", tmp_path / "k.usdc", "--guides", "6"]) == 0
    assert f" 6 strands, {6 * N} particles" in capsys.readouterr().out
    # a fraction that rounds to no strand: 1 guide, and one line saying so (it was silent)
    assert cli.main(["simulate", str(src), "-o", str(tmp_path / "tiny.usdc"), "--guides", "0.001",
                     "--device", "cpu"]) == 0
    captured = capsys.readouterr()
    assert f" 1 strand, {N} particles" in captured.out
    lines = [line for line in captured.err.splitlines() if "--guides 0.001" in line]
    assert lines == [f"dftl-warp: warning: {src}: /World/Hair: --guides 0.001 of its 40 strands is 0.04 strands: "
                     "1 guide simulated"], captured.err


def test_guides_output_binding_writes_the_guides_and_the_binding(tmp_path, capsys):
    src = tmp_path / "groom.usda"
    groom_stage(src, turn=40.0)
    out = tmp_path / "out.usda"
    assert run([src, "-o", out, "--guides-output", "binding"]) == 0
    stage = Usd.Stage.Open(str(out))
    hair = stage.GetPrimAtPath("/World/Head/Offset/Hair")
    assert hair.GetAttribute("points").GetNumTimeSamples() == 0
    assert stage.GetPrimAtPath("/World/Head/Guides").GetAttribute("points").GetNumTimeSamples() == FRAMES
    pv = UsdGeom.PrimvarsAPI(hair)
    ids, w = pv.GetPrimvar("dftl:guideIds"), pv.GetPrimvar("dftl:guideWeights")
    assert ids.GetInterpolation() == "uniform" and ids.GetElementSize() == 4
    weights = np.array(w.Get()).reshape(40, 4)
    np.testing.assert_allclose(weights.sum(axis=1), 1.0, atol=1e-6)
    assert len(pv.GetPrimvar("dftl:guideOffsets").Get()) == 40 * N
    assert len(pv.GetPrimvar("dftl:guideParam").Get()) == 40 * N

    dense = tmp_path / "dense.usda"
    s = new_stage(dense, start=1, end=3)
    rp, rc = strands(RENDER_ANGLES)
    add_curves(s, "/World/Hair", rp, rc)
    s.Save()
    out = tmp_path / "dense_out.usda"
    assert run([dense, "-o", out, "--guides", "5", "--guides-output", "binding"]) == 0
    stage = Usd.Stage.Open(str(out))
    g = UsdGeom.BasisCurves(stage.GetPrimAtPath("/World/Hair_guides"))
    assert g and len(g.GetCurveVertexCountsAttr().Get()) == 5
    assert g.GetPointsAttr().GetNumTimeSamples() == 3
    assert stage.GetPrimAtPath("/World/Hair").GetRelationship("dftl:guides").GetTargets() == [
        Sdf.Path("/World/Hair_guides")]


def test_guides_output_binding_is_complete_when_it_is_moved_into_place(tmp_path, monkeypatch):
    """The binding was authored on the output after the writer had renamed it into place (reopened
    and saved in place: neither atomic nor flushed to the disk). Now the file renamed onto the output
    already holds it, and the output is not touched after."""
    import dftl_warp.output.usd as usd_output

    moved = []

    def replace_file(tmp, target, **kwargs):
        layer = Sdf.Layer.OpenAsAnonymous(str(tmp))
        moved.append(layer.GetPropertyAtPath("/World/Hair.primvars:dftl:guideIds") is not None
                     and layer.GetPrimAtPath("/World/Hair_guides").specifier == Sdf.SpecifierDef)
        real_replace(tmp, target, **kwargs)
        moved.append(Path(target).read_bytes())

    real_replace = usd_output.replace_file
    monkeypatch.setattr(usd_output, "replace_file", replace_file)
    dense = tmp_path / "dense.usda"
    s = new_stage(dense, start=1, end=2)
    rp, rc = strands(RENDER_ANGLES[:10])
    add_curves(s, "/World/Hair", rp, rc)
    s.Save()
    out = tmp_path / "out.usdc"
    assert run([dense, "-o", out, "--guides", "3", "--guides-output", "binding"]) == 0
    assert moved[0] is True, "the file moved into place had no binding"
    assert out.read_bytes() == moved[1], "the output was changed after it was moved into place"


def _error(argv, capsys):
    assert run(argv) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1, err
    return err


def test_input_errors(tmp_path, capsys):
    src = tmp_path / "bad.usda"
    groom_stage(src)
    stage = Usd.Stage.Open(str(src))
    rel = stage.GetPrimAtPath("/World/Head/Offset/Hair").GetRelationship("dftl:guides")
    rel.SetTargets([Sdf.Path("/World/Nope")])
    stage.Save()
    err = _error([src, "-o", tmp_path / "o.usdc"], capsys)
    assert str(src) in err and "/World/Head/Offset/Hair" in err and "/World/Nope: no such prim" in err

    rel.SetTargets([Sdf.Path("/World/Head")])
    stage.Save()
    err = _error([src, "-o", tmp_path / "o.usdc"], capsys)
    assert "/World/Head/Offset/Hair" in err and "not a BasisCurves prim" in err

    rel.SetTargets([Sdf.Path("/World/Head/Guides")])
    set_attr(stage.GetPrimAtPath("/World/Head/Offset/Hair"), "dftl:solver", "Token", "pbd")
    stage.Save()
    err = _error([src, "-o", tmp_path / "o.usdc"], capsys)
    assert str(src) in err and "/World/Head/Offset/Hair" in err and "dftl:solver" in err and "conflicts" in err

    dense = tmp_path / "dense.usda"
    s = new_stage(dense, start=1, end=3)
    rp, rc = strands(RENDER_ANGLES)
    add_curves(s, "/World/Hair", rp, rc)
    s.Save()
    err = _error([dense, "-o", tmp_path / "o.usdc", "--guides", "100"], capsys)
    assert str(dense) in err and "/World/Hair" in err and "100 guides" in err and "40 strands" in err
    assert not (tmp_path / "o.usdc").exists()


def test_info_says_a_render_prim_is_deformed_from_its_guides_not_simulated(tmp_path, capsys):
    import json

    src = tmp_path / "g.usda"
    groom_stage(src)
    assert cli.main(["info", str(src)]) == 0
    out = capsys.readouterr().out
    # it said "/World/Head/Offset/Hair: 40 strands ...; solver dftl": a prim simulate never simulates
    assert (f"/World/Head/Offset/Hair: 40 strands, {40 * N} particles, linear, nonperiodic; not simulated: "
            "deformed from its guides /World/Head/Guides") in out
    assert f"/World/Head/Guides: 8 strands, {8 * N} particles, linear, nonperiodic; solver dftl" in out
    assert "the step is the bare DFTL step" in out
    assert cli.main(["info", str(src), "--json"]) == 0
    curves = {c["path"]: c for c in json.loads(capsys.readouterr().out)["curves"]}
    assert curves["/World/Head/Offset/Hair"]["solver"] is None
    assert curves["/World/Head/Offset/Hair"]["guides"] == ["/World/Head/Guides"]
    assert (curves["/World/Head/Guides"]["solver"], curves["/World/Head/Guides"]["guides"]) == ("dftl", [])


def test_info_counts_a_render_prim_as_its_binding_not_as_simulated_strands(tmp_path):
    """Memory: the render prim adds its binding to the guides (16 n + 40 B a strand of n vertices,
    docs/guides.md), not a simulation of its strands."""
    from dftl_warp.commands.info import describe
    from dftl_warp.usd.read import read_scene

    src = tmp_path / "g.usda"
    groom_stage(src)
    both = describe(read_scene(str(src)))
    guides = describe(read_scene(str(src), prims=["/World/Head/Guides"]))
    binding = 16 * 40 * N + 40 * 40
    for p in ("float32", "float64"):
        assert both["device_bytes"][p] - guides["device_bytes"][p] == binding, (p, both["device_bytes"],
                                                                                guides["device_bytes"])


@pytest.mark.parametrize("guides", ["1", "3"])
def test_render_roots_stay_where_the_groom_puts_them(tmp_path, guides):
    """The guides' first segments swing as they fall; the render strands' roots are pinned to the
    scalp (their prim), not carried around the guides' roots by the swinging root frames."""
    src, rp = dense_stage(tmp_path)
    out = tmp_path / "out.usdc"
    assert run([src, "-o", out, "--guides", guides]) == 0
    got = composed_samples(out, "/World/Hair")
    roots = np.arange(40) * N
    for t in got:
        np.testing.assert_allclose(got[t][roots], rp[roots], atol=2e-6)
    tips = (got[4.0] - got[1.0]).reshape(40, N, 3)[:, -1]
    assert np.linalg.norm(tips, axis=1).min() > 1e-3  # every strand moved


def test_guides_output_binding_refuses_to_overwrite_a_prim_named_like_its_guides(tmp_path, capsys):
    """--guides-output binding writes the guides picked from /World/Hair to /World/Hair_guides: a prim
    already there (here another groom) would be overwritten in the composed output."""
    src = tmp_path / "clash.usda"
    stage = new_stage(src, start=1, end=3)
    rp, rc = strands(RENDER_ANGLES)
    add_curves(stage, "/World/Hair", rp, rc)
    gp, gc = strands(GUIDE_ANGLES, radius=0.2)
    add_curves(stage, "/World/Hair_guides", gp, gc)
    stage.Save()
    out = tmp_path / "out.usda"
    err = _error([src, "-o", out, "--guides", "5", "--guides-output", "binding"], capsys)
    assert str(src) in err and "/World/Hair_guides" in err and "--guides-output binding" in err, err
    assert not out.exists()


def test_what_the_render_strands_approximate_is_said(tmp_path, capsys):
    """Render strands are not collided (they may end inside a collider) and a lone guide has nothing
    to fix its twist: each is one warning naming the prim, not a silent approximation."""
    src = tmp_path / "head.usda"
    stage = new_stage(src, start=1, end=2)
    rp, rc = strands(RENDER_ANGLES)
    add_curves(stage, "/World/Hair", rp, rc)
    skull = UsdGeom.Sphere.Define(stage, "/World/Skull")
    skull.CreateRadiusAttr(0.09)   # under the roots, at 0.1
    UsdPhysics.CollisionAPI.Apply(skull.GetPrim())
    stage.Save()
    for guides, lone in (("1", True), ("4", False)):
        argv = ["simulate", str(src), "-o", str(tmp_path / f"o{guides}.usdc"), "--device", "cpu", "--guides", guides]
        assert cli.main(argv) == 0
        warned = [w for w in capsys.readouterr().err.splitlines() if "warning" in w and "/World/Hair" in w]
        assert sum("/World/Skull" in w and "not collided" in w for w in warned) == 1, warned
        assert sum("one guide" in w for w in warned) == lone, warned
