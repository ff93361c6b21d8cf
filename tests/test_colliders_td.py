"""Colliders as a TD authors them: a non-uniformly scaled Sphere is its ellipsoid (exact signed
distance), a non-uniformly scaled Capsule is the enclosing capsule with one warning naming the
prim, Mesh ``holeIndices`` and ``orientation = "leftHanded"`` are honoured."""

import numpy as np
import warp as wp
from pxr import Gf, UsdGeom, UsdPhysics, Vt
from usd_stages import add_curves, chain, composed_samples, new_stage

from dftl_warp.features.colliders import Capsule, Ellipsoid
from dftl_warp.kernels.features.analytic import ellipsoid_sdf_func
from dftl_warp.simulation.simulate import simulate_usd
from dftl_warp.usd.read import read_scene


def ellipsoid_distance(q, e, iterations=200):
    """Signed distance to the ellipsoid of semi-axes ``e`` by bisection on Eberly's function
    (independent of the kernel's Newton iteration), float64."""
    y = np.maximum(np.abs(q), 1e-12)
    m = np.min(e) ** 2
    # u = t + min(e)^2 > 0, bisected geometrically (the root sits near 0 on the medial surface)
    u_lo = np.full(len(y), 1e-300)
    u_hi = np.full(len(y), np.linalg.norm(y * e, axis=1) + 1.0 + m)
    for _ in range(iterations):
        u = np.sqrt(u_lo * u_hi)
        g = ((e * y / (u[:, None] + (e ** 2 - m))) ** 2).sum(1) - 1
        u_lo = np.where(g > 0, u, u_lo)
        u_hi = np.where(g > 0, u_hi, u)
    x = e ** 2 * y / (u[:, None] + (e ** 2 - m))
    d = np.linalg.norm(y - x, axis=1)
    return np.where(((q / e) ** 2).sum(1) < 1, -d, d)


def test_ellipsoid_signed_distance_is_exact():
    rng = np.random.default_rng(1)
    e = np.array([0.3, 0.1, 0.2])
    q = rng.normal(size=(3000, 3)) * 0.25
    q[:20, 1] = 0.0          # on symmetry planes and the medial disc
    q[20:40] = 0.0
    q[20:40, 0] = rng.uniform(-0.15, 0.15, 20)
    q[40:80] = e * (q[40:80] / np.linalg.norm(q[40:80] / e, axis=1)[:, None])   # on the surface
    ref = ellipsoid_distance(q, e)
    for scalar, tol in ((wp.float64, 1e-8), (wp.float32, 2e-6)):
        vec3 = wp.types.vector(3, scalar)
        sdf = ellipsoid_sdf_func(scalar)

        @wp.kernel(module="unique")
        def query(q: wp.array(dtype=vec3), size: vec3, d: wp.array(dtype=scalar), n: wp.array(dtype=vec3)):
            i = wp.tid()
            a, b = sdf(q[i], size, vec3())
            d[i] = a
            n[i] = b

        f = np.float64 if scalar == wp.float64 else np.float32
        qa = wp.array(q.astype(f), dtype=vec3, device="cpu")
        d = wp.zeros(len(q), dtype=scalar, device="cpu")
        n = wp.zeros(len(q), dtype=vec3, device="cpu")
        wp.launch(query, dim=len(q), inputs=[qa, vec3(*e), d, n], device="cpu")
        d, n = d.numpy().astype(np.float64), n.numpy().astype(np.float64)
        assert np.abs(d - ref).max() < tol
        closest = q - d[:, None] * n        # on the surface, where n is the surface's normal
        assert np.abs(np.linalg.norm(closest / e, axis=1) - 1).max() < 20 * tol
        grad = closest / e ** 2
        assert np.abs(n - grad / np.linalg.norm(grad, axis=1)[:, None]).max() < 50 * tol


def _sphere(stage, path, radius, scale, translate=(0.0, 0.0, 0.0)):
    s = UsdGeom.Sphere.Define(stage, path)
    s.CreateRadiusAttr(radius)
    s.AddTranslateOp().Set(Gf.Vec3d(*translate))
    s.AddScaleOp().Set(Gf.Vec3f(*scale))
    UsdPhysics.CollisionAPI.Apply(s.GetPrim())
    return s


def test_hair_rests_on_a_scaled_sphere_as_on_its_ellipsoid(tmp_path):
    radii = np.array([0.2, 0.06, 0.12])      # radius 0.1 scaled (2, 0.6, 1.2)
    hair_radius = 0.002
    stage = new_stage(tmp_path / "in.usda", start=1, end=48)
    pts = np.concatenate([chain(21, 0.015, origin=(-0.02, 0.066, z)) for z in (-0.06, -0.03, 0.0, 0.03, 0.06)])
    add_curves(stage, "/World/Hair", pts, [21] * 5, widths=2 * hair_radius)
    _sphere(stage, "/World/Head", 0.1, (2.0, 0.6, 1.2))
    stage.Save()
    out = tmp_path / "out.usdc"
    summary = simulate_usd(tmp_path / "in.usda", out, substeps=10)
    assert not [w for w in summary.warnings if "/World/Head" in w]   # exact: no approximation
    samples = composed_samples(out, "/World/Hair")
    worst = np.inf
    for x in samples.values():
        worst = min(worst, ellipsoid_distance(x, radii).min())
    assert worst > hair_radius * (1 - 0.02)          # never inside the ellipsoid's contact distance
    x = samples[48.0]
    d = ellipsoid_distance(x, radii)
    resting = np.abs(d - hair_radius) < 0.02 * hair_radius
    assert resting.sum() >= 10                       # lying on the ellipsoid's surface
    # where a sphere of the largest scale (0.2) would have held it off, the hair lies on the ellipsoid
    assert (np.linalg.norm(x, axis=1) < 0.2 - 0.02).sum() >= 10
    assert x[:, 1].min() < -0.05                     # and it drapes down its side


def test_scaled_capsule_encloses_the_authored_one_and_warns_once(tmp_path):
    stage = new_stage(tmp_path / "in.usda", start=1, end=2)
    add_curves(stage, "/World/Hair", chain(5, 0.01, origin=(0.0, 0.5, 0.0)), [5], widths=0.002)
    cap = UsdGeom.Capsule.Define(stage, "/World/Arm")
    cap.CreateRadiusAttr(0.05)
    cap.CreateHeightAttr(0.2)
    cap.CreateAxisAttr("Z")
    cap.AddScaleOp().Set(Gf.Vec3f(1.0, 1.5, 2.0))
    UsdPhysics.CollisionAPI.Apply(cap.GetPrim())
    stage.Save()
    summary = simulate_usd(tmp_path / "in.usda", tmp_path / "out.usdc")
    mine = [w for w in summary.warnings if "/World/Arm" in w]
    assert len(mine) == 1 and "capsule" in mine[0]
    offset = float(mine[0].split("up to ")[1].split()[0])
    # the capsule made contains the scaled one: every point of the authored surface is inside it
    scene = read_scene(tmp_path / "in.usda")
    prim = scene.colliders[0]
    import warnings
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        shape = Capsule.from_prim(prim, np.zeros(3), np.array([0, 0, 0, 1.0]), np.array([1.0, 1.5, 2.0]), {})
    rng = np.random.default_rng(0)
    u = rng.normal(size=(20000, 3))
    u /= np.linalg.norm(u, axis=1)[:, None]
    unit = 0.05 * u + np.where(u[:, 2:] > 0, 1, -1) * [0, 0, 0.1]      # the unit capsule's surface
    side = rng.uniform(-0.1, 0.1, 5000)
    ring = rng.uniform(0, 2 * np.pi, 5000)
    unit = np.concatenate([unit, np.stack([0.05 * np.cos(ring), 0.05 * np.sin(ring), side], 1)])
    surface = unit * [1.0, 1.5, 2.0]
    a = np.clip(surface[:, 2], -shape.half_height, shape.half_height)
    d = np.linalg.norm(surface - a[:, None] * [0, 0, 1], axis=1) - shape.radius
    assert d.max() < 1e-12                      # contained
    assert -d.min() <= offset * 1.01 and offset < 0.05     # the warning says how far off it is


def _cube_faces(h):
    """Points of the cube [-h, h]^3 and its quads, counter-clockwise seen from outside."""
    p = np.array([[x, y, z] for x in (-h, h) for y in (-h, h) for z in (-h, h)], dtype=np.float64)
    quads = [[0, 1, 3, 2], [4, 6, 7, 5], [0, 4, 5, 1], [2, 3, 7, 6], [0, 2, 6, 4], [1, 5, 7, 3]]
    return p, np.array(quads)


def _mesh(stage, path, points, faces, **attrs):
    m = UsdGeom.Mesh.Define(stage, path)
    m.CreateFaceVertexCountsAttr(Vt.IntArray([len(f) for f in faces]))
    m.CreateFaceVertexIndicesAttr(Vt.IntArray([int(i) for f in faces for i in f]))
    m.CreatePointsAttr(Vt.Vec3fArray.FromNumpy(np.asarray(points, dtype=np.float32)))
    if "orientation" in attrs:
        m.CreateOrientationAttr(attrs["orientation"])
    if "holes" in attrs:
        m.CreateHoleIndicesAttr(Vt.IntArray([int(i) for i in attrs["holes"]]))
    UsdPhysics.CollisionAPI.Apply(m.GetPrim())
    return m


def test_left_handed_mesh_keeps_its_inside_inside(tmp_path):
    h, hair_radius = 0.05, 0.001
    pts, quads = _cube_faces(h)
    stage = new_stage(tmp_path / "in.usda", start=1, end=36)
    _mesh(stage, "/World/Box", pts, quads[:, ::-1], orientation="leftHanded")   # clockwise, left-handed
    strands = np.concatenate([chain(16, 0.01, origin=(-0.03, h + 0.004, z)) for z in (-0.02, 0.0, 0.02)])
    add_curves(stage, "/World/Hair", strands, [16] * 3, widths=2 * hair_radius)
    stage.Save()
    scene = read_scene(tmp_path / "in.usda")
    tri = scene.colliders[0].triangles
    p = scene.colliders[0].mesh_points
    a, b, c = p[tri[:, 0]], p[tri[:, 1]], p[tri[:, 2]]
    assert np.einsum("ij,ij->i", a, np.cross(b - a, c - a)).sum() / 6 > 0   # outward: positive volume
    out = tmp_path / "out.usdc"
    simulate_usd(tmp_path / "in.usda", out, substeps=10)
    samples = composed_samples(out, "/World/Hair")
    for x in samples.values():
        outside = np.linalg.norm(np.maximum(np.abs(x) - h, 0.0), axis=1)
        inside = np.min(h - np.abs(x), axis=1)
        d = np.where(outside > 0, outside, -inside)
        assert d.min() > 0.9 * hair_radius
    x = samples[36.0]
    assert x[:, 1].min() < 0.0                 # draped over the edge, down the box's side
    assert (np.abs(x[:, 1] - (h + hair_radius)) < 0.05 * hair_radius).sum() >= 6   # lying on the top


def test_mesh_holes_let_hair_through_where_faces_were_removed(tmp_path):
    n, cell = 8, 0.05
    g = np.arange(n + 1) * cell - n * cell / 2
    pts = np.array([[x, 0.0, z] for z in g for x in g])
    faces, holes = [], []
    for j in range(n):
        for i in range(n):
            a = j * (n + 1) + i
            faces.append([a, a + n + 1, a + n + 2, a + 1])        # counter-clockwise seen from +y
            if 2 <= i < 6 and 2 <= j < 6:
                holes.append(len(faces) - 1)
    stage = new_stage(tmp_path / "in.usda", start=1, end=36)
    _mesh(stage, "/World/Ground", pts, faces, holes=holes)
    over_hole = chain(7, 0.01, origin=(-0.07, 0.03, 0.0))
    over_floor = chain(7, 0.01, origin=(0.12, 0.03, 0.15))
    add_curves(stage, "/World/Hair", np.concatenate([over_hole, over_floor]), [7, 7], widths=0.002)
    stage.Save()
    scene = read_scene(tmp_path / "in.usda")
    assert len(scene.colliders[0].triangles) == 2 * (n * n - len(holes))
    out = tmp_path / "out.usdc"
    simulate_usd(tmp_path / "in.usda", out, substeps=10)
    x = composed_samples(out, "/World/Hair")[36.0]
    assert x[:7, 1].min() < -0.025              # hanging through the hole (tip 6 cm below the root)
    assert x[7:, 1].min() > 0.001 * 0.9         # resting on the floor
