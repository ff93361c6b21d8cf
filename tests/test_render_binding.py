"""``dftl-warp render`` of a guide binding cache (``simulate --guides-output binding``): the render curves
are deformed by their simulated guides at each frame, as ``--guides-output curves`` writes them (they
were drawn at rest, with a warning). A binding that cannot be used is one line, exit 2, no image."""

import numpy as np
import pytest
from pxr import Gf, Sdf, Usd, UsdGeom, Vt
from usd_stages import add_curves, animated_xform, new_stage

from dftl_warp import cli
from dftl_warp.render import usd_scene
from dftl_warp.usd.scene import transform_points

N, FRAMES = 8, 5


def strands(angles, radius=0.1, length=0.2, curl=0.0):
    pts = []
    for a in angles:
        out, side = np.array([np.cos(a), 0.0, np.sin(a)]), np.array([-np.sin(a), 0.0, np.cos(a)])
        for i in range(N):
            s = i / (N - 1)
            pts.append(radius * out + length * s * (0.6 * out + np.array([0.0, -0.8, 0.0]))
                       + curl * s * np.sin(3 * np.pi * s) * side)
    return np.array(pts), [N] * len(angles)


def groom(path):
    """A head turning 60 deg about Y; 8 guides under it, 30 render curves (rel dftl:guides) under an
    extra rotation, both falling under gravity from a pose they do not rest in."""
    stage = new_stage(path, start=1, end=FRAMES)
    animated_xform(stage, "/World/Head", rotate_y={1: 0.0, FRAMES: 60.0})
    off = UsdGeom.Xform.Define(stage, "/World/Head/Offset")
    off.AddRotateYOp().Set(25.0)
    gp, gc = strands(np.linspace(0, 2 * np.pi, 8, endpoint=False))
    add_curves(stage, "/World/Head/Guides", gp, gc)
    rp, rc = strands(np.linspace(0.1, 2 * np.pi + 0.1, 30, endpoint=False), radius=0.105, curl=0.01)
    inv = np.linalg.inv(np.array(off.GetLocalTransformation(), dtype=np.float64))
    add_curves(stage, "/World/Head/Offset/Hair", transform_points(inv, rp), rc)
    stage.GetPrimAtPath("/World/Head/Offset/Hair").CreateRelationship("dftl:guides").SetTargets(
        [Sdf.Path("/World/Head/Guides")])
    stage.Save()


def simulate(src, out, *args):
    return cli.main(["simulate", str(src), "-o", str(out), "--device", "cpu", "--quiet", *args])


def render(*args):
    return cli.main(["render", *map(str, args), "--resolution", "32x24", "--spp", "1", "-q"])


@pytest.fixture(scope="module")
def caches(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("bound")
    src = tmp / "groom.usda"
    groom(src)
    curves, bound = tmp / "curves.usda", tmp / "binding.usda"
    assert simulate(src, curves) == 0 and simulate(src, bound, "--guides-output", "binding") == 0
    return tmp, curves, bound


def test_a_binding_cache_renders_the_curves_its_guides_carry(caches, capsys):
    """Every frame, the drawn strands of the binding cache are those of the curves cache of the same run
    (float32 round-off), not the rest pose (which is 10 cm away by the last frame)."""
    tmp, curves, bound = caches
    a, b = Usd.Stage.Open(str(curves)), Usd.Stage.Open(str(bound))
    rest = usd_scene.read_render_scene(b, None).points
    for t in range(1, FRAMES + 1):
        want = usd_scene.read_render_scene(a, t).points
        got = usd_scene.read_render_scene(b, t).points
        np.testing.assert_allclose(got, want, atol=2e-7)
        if t == FRAMES:
            assert np.abs(want - rest).max() > 0.05
    # the groom has no widths: drawn at a default width with a warning (tests/test_render_audit.py), and nothing else
    widths = (f"{bound}: 2 BasisCurves prims (/World/Head/Offset/Hair, /World/Head/Guides) without widths or "
              "primvars:widths: drawn at a default width, 1/1000 of each prim's bounding-box diagonal")
    assert usd_scene.render_notes(b) == [widths]
    capsys.readouterr()
    out = tmp / "bound.png"
    assert render(bound, "--frame", FRAMES, "-o", out) == 0
    # nothing is drawn at rest any more: the widths are the only thing to warn about
    assert capsys.readouterr().err.splitlines() == [f"dftl-warp: warning: {widths}"]


def test_a_dense_prim_bound_to_guides_picked_from_it_renders_as_its_curves(tmp_path):
    """``--guides 4``: the binding cache names /World/Hair_guides; the render curves follow them. The
    guides, which the render curves contain, were drawn a second time on top of them; /World/Hair_guides
    is now of purpose guide, and the binding cache draws what the curves cache draws."""
    src = tmp_path / "dense.usda"
    stage = new_stage(src, start=1, end=3)
    rp, rc = strands(np.linspace(0.1, 2 * np.pi + 0.1, 24, endpoint=False), curl=0.01)
    add_curves(stage, "/World/Hair", rp, rc)
    stage.Save()
    curves, bound = tmp_path / "c.usda", tmp_path / "b.usda"
    assert simulate(src, curves, "--guides", "4") == 0
    assert simulate(src, bound, "--guides", "4", "--guides-output", "binding") == 0
    a, b = Usd.Stage.Open(str(curves)), Usd.Stage.Open(str(bound))
    assert UsdGeom.Imageable(b.GetPrimAtPath("/World/Hair_guides")).ComputePurpose() == "guide"
    for t in (1, 3):
        got = usd_scene.read_render_scene(b, t)
        want = usd_scene.read_render_scene(a, t)
        assert got.curve_vertex_counts.tolist() == want.curve_vertex_counts.tolist() == [N] * len(rc)
        np.testing.assert_allclose(got.points, want.points, atol=2e-7)


def _broken(caches, tmp_path, change):
    """A copy of the binding cache (beside a copy of its input, which it sublayers) changed by ``change``."""
    folder, _, bound = caches
    path = tmp_path / "broken.usda"
    Sdf.Layer.FindOrOpen(str(folder / "groom.usda")).Export(str(tmp_path / "groom.usda"))
    Sdf.Layer.FindOrOpen(str(bound)).Export(str(path))
    stage = Usd.Stage.Open(str(path))
    change(stage.GetPrimAtPath("/World/Head/Offset/Hair"))
    stage.Save()
    return path


@pytest.mark.parametrize("change, message", [
    (lambda p: p.GetRelationship("dftl:guides").SetTargets([]),
     "dftl:guides has no targets; expected one or more BasisCurves prims"),
    (lambda p: p.RemoveProperty("primvars:dftl:guideOffsets"),
     "a guide binding without primvars:dftl:guideOffsets: cannot deform its curves (write it with simulate "
     "--guides-output binding)"),
    (lambda p: UsdGeom.PrimvarsAPI(p).GetPrimvar("dftl:guideIds").Set(Vt.IntArray([9] * 120)),
     "primvars:dftl:guideIds[0] = 9: not a guide index in 0..7 (8 curves in /World/Head/Guides)"),
    (lambda p: UsdGeom.PrimvarsAPI(p).GetPrimvar("dftl:guideParam").Set(Vt.FloatArray([0.0] * 7)),
     "primvars:dftl:guideParam has 7 values, expected 240 finite ones"),
])
def test_a_binding_that_cannot_be_used_is_one_line(caches, tmp_path, capsys, change, message):
    path = _broken(caches, tmp_path, change)
    capsys.readouterr()
    out = tmp_path / "out.png"
    assert render(path, "--frame", 2, "-o", out) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [f"dftl-warp: error: {path}: /World/Head/Offset/Hair: {message}"], err
    assert not out.exists()


def test_the_render_roots_stay_where_the_render_prim_holds_them(caches, tmp_path):
    """The binding is in world space; a render prim moved 0.5 up after the simulation has its roots, and
    so its strands (translated whole, as simulate pins them), drawn 0.5 higher than in the curves cache."""
    def shift(prim):
        UsdGeom.Xformable(prim).AddTranslateOp(opSuffix="later").Set(Gf.Vec3d(0.0, 0.5, 0.0))
    path = _broken(caches, tmp_path, shift)
    moved = usd_scene.read_render_scene(Usd.Stage.Open(str(path)), 3).points
    _, curves, _ = caches
    plain = usd_scene.read_render_scene(Usd.Stage.Open(str(curves)), 3).points
    hair = 30 * N   # /World/Head/Offset/Hair is drawn first, then /World/Head/Guides, where they were
    np.testing.assert_allclose(moved[hair:], plain[hair:], atol=1e-7)
    np.testing.assert_allclose(moved[:hair] - plain[:hair], np.tile([0.0, 0.5, 0.0], (hair, 1)), atol=1e-6)
