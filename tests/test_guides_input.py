"""Guides that cannot carry their render strands, and guide input errors (docs/guides.md):
a guide with a repeated point is refused (it has no frame there), an inactive guide prim is refused,
and at rest the render strands equal the authored groom for k = 1 and k > 1."""

import numpy as np
import pytest
from pxr import Sdf, UsdGeom
from usd_stages import add_curves, composed_samples, new_stage

from dftl_warp import cli
from dftl_warp.guides import bind, deform_reference

N = 8


def groom(count=50, seed=0):
    rng = np.random.default_rng(seed)
    pts = []
    for _ in range(count):
        r = np.r_[rng.uniform(-0.1, 0.1), 0.0, rng.uniform(-0.1, 0.1)]
        for i in range(N):
            pts.append(r + [0.01 * np.sin(i), -0.02 * i, 0.003 * i * i])
    return np.array(pts), [N] * count


@pytest.mark.parametrize("k", [1, 2, 4])
@pytest.mark.parametrize("frames", ["blend", "per-guide"])
def test_rest_is_reproduced_for_any_k(k, frames):
    points, counts = groom()
    guides = np.concatenate([points[i * N:(i + 1) * N] for i in (1, 10, 20, 30)])
    b = bind(guides, [N] * 4, points, counts, k=k, frames=frames)
    assert np.abs(deform_reference(b, guides) - points).max() < 1e-9
    from dftl_warp.guides import GuideDeformer

    out = GuideDeformer(b, device="cpu").deform(guides).numpy()
    assert np.abs(out - points).max() < 2e-6


def test_lone_guide_reproduces_rest():
    points, counts = groom()
    guide = points[N:2 * N]
    b = bind(guide, [N], points, counts, k=1)
    assert np.abs(deform_reference(b, guide) - points).max() < 1e-9


@pytest.mark.parametrize("k", [1, 2])
@pytest.mark.parametrize("repeated", [1, 4, 7])
def test_guide_with_a_repeated_point_is_refused(k, repeated):
    points, counts = groom()
    guides = np.concatenate([points[N:2 * N], points[10 * N:11 * N]])
    guides[repeated] = guides[repeated - 1]
    with pytest.raises(ValueError, match=rf"guide 0: points {repeated - 1} and {repeated} coincide"):
        bind(guides, [N, N], points, counts, k=k)


def scene(path, *, repeat=None, inactive=False):
    stage = new_stage(path, start=1, end=3)
    UsdGeom.Xform.Define(stage, "/World/Head")
    points, counts = groom(20)
    guide = points[N:2 * N].copy()
    if repeat is not None:
        guide[repeat] = guide[repeat - 1]
    add_curves(stage, "/World/Head/Guides", guide, [N])
    add_curves(stage, "/World/Head/Hair", points, counts)
    stage.GetPrimAtPath("/World/Head/Hair").CreateRelationship("dftl:guides").SetTargets(
        [Sdf.Path("/World/Head/Guides")])
    if inactive:
        stage.GetPrimAtPath("/World/Head/Guides").SetActive(False)
    stage.Save()
    return points


def simulate(argv):
    return cli.main(["simulate", *map(str, argv), "--device", "cpu", "--quiet", "--end", "2"])


def one_error(capsys, argv, out):
    assert simulate(argv) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "Traceback" not in err, err
    assert not out.exists()
    return err


def test_cli_refuses_a_guide_with_a_repeated_point(tmp_path, capsys):
    src, out = tmp_path / "g.usda", tmp_path / "o.usdc"
    scene(src, repeat=1)
    err = one_error(capsys, [src, "-o", out], out)
    assert str(src) in err and "/World/Head/Guides" in err and "curve 0" in err and "points 0 and 1" in err


def test_cli_lone_guide_at_rest_reproduces_the_groom(tmp_path):
    src, out = tmp_path / "g.usda", tmp_path / "o.usdc"
    points = scene(src)
    assert simulate([src, "-o", out]) == 0
    got = composed_samples(out, "/World/Head/Hair")
    assert np.abs(got[1.0] - points).max() < 2e-6


def test_cli_refuses_an_inactive_guide_prim(tmp_path, capsys):
    src, out = tmp_path / "g.usda", tmp_path / "o.usdc"
    scene(src, inactive=True)
    err = one_error(capsys, [src, "-o", out], out)
    assert str(src) in err and "/World/Head/Guides" in err and "inactive" in err


def test_guides_picked_with_a_repeated_point_are_refused(tmp_path, capsys):
    src, out = tmp_path / "d.usda", tmp_path / "o.usdc"
    stage = new_stage(src, start=1, end=3)
    points, counts = groom(20)
    points[3 * N + 2] = points[3 * N + 1]
    add_curves(stage, "/World/Hair", points, counts)
    stage.Save()
    assert simulate([src, "-o", out, "--guides", "100%"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "/World/Hair: curve 3" in err and "points 1 and 2" in err, err
    assert not out.exists()
