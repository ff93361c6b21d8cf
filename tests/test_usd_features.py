"""Features from USD: colliders from UsdPhysics.CollisionAPI prims (static, animated, deforming
meshes), scene and per-curve ``dftl:`` feature attributes, roots bound to a deforming mesh, and
what ``dftl-warp info`` reports."""

import numpy as np
import pytest
from pxr import Gf, Sdf, UsdGeom, UsdPhysics, Vt
from usd_stages import add_curves, animated_xform, chain, composed_samples, new_stage, set_attr

from dftl_warp import cli
from dftl_warp.simulation.simulate import simulate_usd


def sphere_collider(stage, path, radius, translate=(0.0, 0.0, 0.0)):
    s = UsdGeom.Sphere.Define(stage, path)
    s.CreateRadiusAttr(radius)
    s.AddTranslateOp().Set(Gf.Vec3d(*translate))
    UsdPhysics.CollisionAPI.Apply(s.GetPrim())
    return s


def quad_mesh(stage, path, points):
    m = UsdGeom.Mesh.Define(stage, path)
    m.CreateFaceVertexCountsAttr(Vt.IntArray([4]))
    m.CreateFaceVertexIndicesAttr(Vt.IntArray([0, 1, 2, 3]))
    m.CreatePointsAttr(Vt.Vec3fArray.FromNumpy(np.asarray(points, dtype=np.float32)))
    return m


def test_strands_drape_on_a_sphere_collider_and_an_animated_capsule_pushes_them(tmp_path):
    stage = new_stage(tmp_path / "in.usda", start=1, end=36)
    pts = np.concatenate([chain(21, 0.02, origin=(-0.2, 0.12, z)) for z in (-0.02, 0.0, 0.02)])
    curves = add_curves(stage, "/World/Hair", pts, [21, 21, 21], widths=0.004)
    sphere_collider(stage, "/World/Ball", 0.1)
    mover = animated_xform(stage, "/World/Mover", translate={1: (0.6, -0.1, 0.0), 36: (-0.6, -0.1, 0.0)})
    cap = UsdGeom.Capsule.Define(stage, "/World/Mover/Pusher")
    cap.CreateRadiusAttr(0.03)
    cap.CreateHeightAttr(0.3)
    cap.CreateAxisAttr("Z")
    UsdPhysics.CollisionAPI.Apply(cap.GetPrim())
    set_attr(cap.GetPrim(), "dftl:friction", "Float", 0.0)
    assert curves and mover
    stage.Save()
    out = tmp_path / "out.usdc"
    summary = simulate_usd(tmp_path / "in.usda", out, substeps=10)
    assert summary.colliders == 2
    samples = composed_samples(out, "/World/Hair")
    worst_ball = worst_capsule = 0.0
    for t, x in samples.items():
        worst_ball = max(worst_ball, (0.1 + 0.002 - np.linalg.norm(x, axis=1)).max())
        centre = np.array([0.6 - 1.2 * (t - 1) / 35, -0.1, 0.0])
        q = x - centre
        axial = np.clip(q[:, 2], -0.15, 0.15)
        worst_capsule = max(worst_capsule, (0.032 - np.linalg.norm(q - axial[:, None] * [0, 0, 1], axis=1)).max())
    assert worst_ball < 0.02 * 0.1 and worst_capsule < 0.05 * 0.03
    # it did drape: the free ends hang below the ball's equator
    assert samples[36.0][:, 1].min() < -0.05


def test_deforming_mesh_collider_and_roots_bound_to_a_deforming_mesh(tmp_path):
    stage = new_stage(tmp_path / "in.usda", start=1, end=12)
    # a ground quad rising from y = -0.3 to y = -0.1; strands hang toward it
    ground = quad_mesh(stage, "/World/Ground", [(-1, -0.3, 1), (1, -0.3, 1), (1, -0.3, -1), (-1, -0.3, -1)])
    pts_attr = ground.GetPointsAttr()
    for f, y in ((1, -0.3), (12, -0.1)):
        pts_attr.Set(Vt.Vec3fArray.FromNumpy(np.array([(-1, y, 1), (1, y, 1), (1, y, -1), (-1, y, -1)],
                                                      dtype=np.float32)), f)
    UsdPhysics.CollisionAPI.Apply(ground.GetPrim())
    # a scalp quad sliding along +x; the roots sit on it
    scalp = quad_mesh(stage, "/World/Scalp", [(-0.1, 0.2, 0.1), (0.1, 0.2, 0.1), (0.1, 0.2, -0.1), (-0.1, 0.2, -0.1)])
    for f, dx in ((1, 0.0), (12, 0.22)):
        scalp.GetPointsAttr().Set(Vt.Vec3fArray.FromNumpy(np.array(
            [(-0.1 + dx, 0.2, 0.1), (0.1 + dx, 0.2, 0.1), (0.1 + dx, 0.2, -0.1), (-0.1 + dx, 0.2, -0.1)],
            dtype=np.float32)), f)
    hair = add_curves(stage, "/World/Hair", np.concatenate([chain(16, 0.025, (0, -1, 0), (x, 0.2, 0.0))
                                                            for x in (-0.05, 0.05)]), [16, 16], widths=0.002)
    hair.GetPrim().CreateRelationship("dftl:rootMesh", custom=True).AddTarget(Sdf.Path("/World/Scalp"))
    stage.Save()
    out = tmp_path / "out.usdc"
    simulate_usd(tmp_path / "in.usda", out, substeps=8)
    samples = composed_samples(out, "/World/Hair")
    gaps = []
    for t, x in samples.items():
        dx = 0.22 * (t - 1) / 11
        np.testing.assert_allclose(x[[0, 16], 0], [-0.05 + dx, 0.05 + dx], atol=1e-5)  # roots ride the scalp
        gaps.append(x[:, 1].min() - (-0.3 + 0.2 * (t - 1) / 11) - 0.001)
    assert min(gaps) > -1e-4  # nothing below the rising ground (hair radius 1 mm) ...
    assert min(gaps) < 1e-4  # ... which did reach the strands and push them up


def test_scene_wind_and_drag(tmp_path):
    """Scene-wide wind and drag blow a hanging chain downwind."""
    stage = new_stage(tmp_path / "in.usda", start=1, end=48)
    scene = UsdPhysics.Scene.Define(stage, "/World/Physics")
    set_attr(scene.GetPrim(), "dftl:drag", "Float", 2.0)
    wind = scene.GetPrim().CreateAttribute("dftl:wind", Sdf.ValueTypeNames.Vector3f, custom=True)
    wind.Set(Gf.Vec3f(0.0, 0.0, 0.0), 1)
    wind.Set(Gf.Vec3f(2.0, 0.0, 0.0), 12)
    add_curves(stage, "/World/Straight", chain(20, 0.01, (0, -1, 0)), [20])
    stage.Save()
    out = tmp_path / "out.usdc"
    simulate_usd(tmp_path / "in.usda", out, substeps=10)
    tip = composed_samples(out, "/World/Straight")[48.0][-1]
    # a hanging chain in a 2 m/s wind with drag 2/s settles at atan(4 / 9.81) = 22 degrees downwind
    assert np.degrees(np.arctan2(tip[0], -(tip[1]))) == pytest.approx(np.degrees(np.arctan(4 / 9.81)), abs=3)


def test_info_lists_features_and_memory(tmp_path, capsys):
    stage = new_stage(tmp_path / "in.usda")
    scene = UsdPhysics.Scene.Define(stage, "/World/Physics")
    set_attr(scene.GetPrim(), "dftl:drag", "Float", 1.0)
    set_attr(scene.GetPrim(), "dftl:hairHair", "Bool", True)
    add_curves(stage, "/World/Hair", chain(10, 0.01), [10])
    sphere_collider(stage, "/World/Ball", 0.1, translate=(0, -1, 0))
    stage.Save()
    assert cli.main(["info", str(tmp_path / "in.usda")]) == 0
    text = capsys.readouterr().out
    assert "features    air drag, hair-hair interaction, sphere colliders" in text
    assert "per strand and" in text and "features included" in text
    assert cli.main(["info", "--json", str(tmp_path / "in.usda")]) == 0
    import json

    d = json.loads(capsys.readouterr().out)
    assert d["feature_flags"] == ["drag", "hair_hair", "spheres"]
    # drag 4 B per strand + hair radius 4 B and the velocity pass's output 12 B per particle; the
    # grid is fixed memory
    assert d["feature_bytes_per_strand"]["float32"] == 4 + 10 * (4 + 12)
    assert d["feature_fixed_bytes"]["float32"] > 0


def test_bad_feature_attribute_is_one_line_error(tmp_path, capsys):
    stage = new_stage(tmp_path / "in.usda")
    hair = add_curves(stage, "/World/Hair", chain(5, 0.01), [5])
    set_attr(hair.GetPrim(), "dftl:drag", "Float", -1.5)
    stage.Save()
    out = tmp_path / "out.usdc"
    assert cli.main(["simulate", str(tmp_path / "in.usda"), "-o", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "/World/Hair: dftl:drag = -1.5: must be >= 0" in err[0]
    assert not out.exists()


@pytest.mark.parametrize("where", ["/World/Hair", "/World/Physics"])
def test_retired_shape_stiffness_is_refused_naming_its_replacement(tmp_path, capsys, where):
    stage = new_stage(tmp_path / "in.usda")
    UsdPhysics.Scene.Define(stage, "/World/Physics")
    add_curves(stage, "/World/Hair", chain(5, 0.01), [5])
    set_attr(stage.GetPrimAtPath(where), "dftl:shapeStiffness", "Float", 0.5)
    stage.Save()
    out = tmp_path / "out.usdc"
    assert cli.main(["simulate", str(tmp_path / "in.usda"), "-o", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    assert f"{where}: dftl:shapeStiffness: shape retention is retired" in err[0]
    assert "elastic rods" in err[0] and "primvars:dftl:bendStiffnessScale" in err[0]
    assert not out.exists()


def hair_hair_patch(path, scale=1.0, order=None):
    """A 10 x 10 patch of 10 cm strands 2.5 mm apart with hair-hair on, under an Xform scaled by
    ``scale`` (its points authored 1 / scale as large), strands in ``order``."""
    stage = new_stage(path, end=3)
    rng = np.random.default_rng(0)
    ys = -np.linspace(0.0, 0.1, 9)
    strands = [np.array([i * 0.0025, 0.0, j * 0.0025]) + rng.normal(0.0, 1e-4, 3)
               + np.stack([0.001 * np.sin(30 * ys), ys, np.zeros(9)], 1) for i in range(10) for j in range(10)]
    if order is not None:
        strands = [strands[k] for k in order]
    UsdGeom.Xform.Define(stage, "/World/Groom").AddScaleOp().Set(Gf.Vec3f(scale, scale, scale))
    add_curves(stage, "/World/Groom/Hair", np.concatenate(strands) / scale, [9] * 100)
    set_attr(stage.GetPrimAtPath("/World"), "dftl:hairHair", "Bool", True)
    stage.Save()
    return path


def test_the_default_hair_hair_cell_is_four_segments_in_the_world_whatever_the_strand_order(tmp_path):
    """The default cell is 4 x the mean segment of the strands as simulated: in the world (a groom
    authored 100 times larger under a 0.01 scale was given a cell 100 times too large, 8.9 m here)
    and within strands (the jumps from each tip to the next root counted as segments: the cell
    depended on the order of the strands and was 0.089 m here instead of 0.050)."""
    from dftl_warp.features import HairHair, find, group_features
    from dftl_warp.usd.read import read_scene

    segment = None
    shuffled = np.random.default_rng(1).permutation(100)
    for name, scale, order in (("plain", 1.0, None), ("scaled", 0.01, None), ("shuffled", 1.0, shuffled)):
        scene = read_scene(str(hair_hair_patch(tmp_path / f"{name}.usda", scale, order)))
        (curve,) = scene.curves
        if segment is None:
            segment = np.mean(np.concatenate([np.linalg.norm(np.diff(s, axis=0), axis=1)
                                              for s in np.split(curve.points, 100)]))
        cell = find(group_features(scene, scene.curves, 1)[0], HairHair).cell_size
        assert cell == pytest.approx(4 * segment, rel=1e-5), name


def test_a_scaled_groom_moves_as_the_same_groom_authored_in_the_world(tmp_path):
    """Hair-hair through an Xform scale: the same strands, in the world, whether authored in metres
    or 100 times larger under a 0.01 scale (6 mm apart after 2 frames, the scaled groom's cell 100
    times too large)."""
    runs = []
    for name, scale in (("plain", 1.0), ("scaled", 0.01)):
        out = tmp_path / f"{name}.usdc"
        simulate_usd(hair_hair_patch(tmp_path / f"{name}.usda", scale), out, precision="float64", device="cpu")
        runs.append(composed_samples(out, "/World/Groom/Hair")[3.0] * scale)
    np.testing.assert_allclose(runs[1], runs[0], atol=1e-6)
