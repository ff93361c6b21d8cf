"""A scene simulates alike in any stage unit (CPU, float64).

The same stage authored in metres and in 1/128 m (every length x 128: a power of two, so every
product of the simulation scales exactly and nothing rounds differently) must give the same
motion to round-off. The colliders' continuous tests once stopped a particle within a fixed
1e-6 stage units of the surface: 1 um in metres, 8 nm in 1/128 m, and the two stages parted by
0.6 mm in 2 frames and 9 mm in 6 frames on a sphere. That tolerance is now a fraction of the
segment's rest length."""

from __future__ import annotations

import numpy as np
import pytest
from pxr import Sdf, Usd, UsdGeom, UsdPhysics, Vt
from test_usd_features import sphere_collider
from usd_stages import add_curves, chain, new_stage

from dftl_warp import cli

SCALE = 128.0


def mesh_ball(stage, path, radius, field: bool, rings=24, segments=32):
    """A closed UV-sphere mesh collider of ``radius`` (stage units), through its field or exactly."""
    theta = np.linspace(0.0, np.pi, rings + 1)[1:-1]
    phi = np.linspace(0.0, 2.0 * np.pi, segments, endpoint=False)
    t, p = np.meshgrid(theta, phi, indexing="ij")
    ring = np.stack([np.sin(t) * np.cos(p), np.cos(t), np.sin(t) * np.sin(p)], -1).reshape(-1, 3)
    pts = np.concatenate([[[0.0, 1.0, 0.0]], ring, [[0.0, -1.0, 0.0]]]) * radius
    at = lambda r, s: 1 + r * segments + s % segments  # noqa: E731
    tris = []
    for s in range(segments):
        tris += [(0, at(0, s + 1), at(0, s)), (len(pts) - 1, at(rings - 2, s), at(rings - 2, s + 1))]
        for r in range(rings - 2):
            a, b, c, d = at(r, s), at(r, s + 1), at(r + 1, s), at(r + 1, s + 1)
            tris += [(a, b, d), (a, d, c)]
    tris = np.array(tris)
    normal = np.cross(pts[tris[:, 1]] - pts[tris[:, 0]], pts[tris[:, 2]] - pts[tris[:, 0]])
    flip = np.sum(normal * pts[tris].mean(1), axis=1) < 0
    tris[flip] = tris[flip][:, ::-1]
    m = UsdGeom.Mesh.Define(stage, path)
    m.CreatePointsAttr(Vt.Vec3fArray.FromNumpy(pts.astype(np.float32)))
    m.CreateFaceVertexCountsAttr(Vt.IntArray([3] * len(tris)))
    m.CreateFaceVertexIndicesAttr(Vt.IntArray(tris.reshape(-1).tolist()))
    UsdPhysics.CollisionAPI.Apply(m.GetPrim())
    m.GetPrim().CreateAttribute("dftl:collisionSdf", Sdf.ValueTypeNames.Bool, custom=True).Set(field)


def run(tmp_path, name, units_per_metre, collider):
    """Positions (m) at frames 2, 4, 6 of 30 strands combed onto a 10 cm ball."""
    s = units_per_metre
    path = tmp_path / f"{name}.usda"
    stage = new_stage(path, start=1, end=6, meters_per_unit=1.0 / s)
    rng = np.random.default_rng(1)
    pts = np.concatenate([chain(12, 0.01 * s, direction=(rng.uniform(-0.5, 0.5), -0.3, rng.uniform(-0.5, 0.5)),
                                origin=(rng.uniform(-0.03, 0.03) * s, 0.105 * s, rng.uniform(-0.03, 0.03) * s))
                          for _ in range(30)])
    add_curves(stage, "/World/Hair", pts, [12] * 30, widths=1e-4 * s)
    if collider == "sphere":
        sphere_collider(stage, "/World/Ball", 0.1 * s)
    else:
        mesh_ball(stage, "/World/Ball", 0.1 * s, field=collider == "mesh field")
    stage.Save()
    out = tmp_path / f"{name}.usdc"
    assert cli.main(["simulate", str(path), "-o", str(out), "--solver", "dftl", "--precision", "float64", "-q"]) == 0
    written = Usd.Stage.Open(str(out))   # held: its prims live as long as it does
    curves = UsdGeom.BasisCurves(written.GetPrimAtPath("/World/Hair"))
    return np.array([np.array(curves.GetPointsAttr().Get(f), dtype=np.float64) / s for f in (2, 4, 6)])


@pytest.mark.parametrize("collider", ["sphere", "mesh exact", "mesh field"])
def test_a_scene_in_metres_and_in_128ths_of_a_metre_moves_alike(tmp_path, collider):
    metres = run(tmp_path, "m", 1.0, collider)
    scaled = run(tmp_path, "scaled", SCALE, collider)
    moved = np.abs(metres[-1] - metres[0]).max()
    assert moved > 1e-3   # the hair falls onto the ball and slides
    # written as float32 points: equal to their rounding
    assert np.abs(metres - scaled).max() <= 1e-6 * 0.2, np.abs(metres - scaled).max(axis=(1, 2))
