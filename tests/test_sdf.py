"""Mesh colliders through a signed distance field (docs/features.md, "Signed distance fields of mesh
colliders"): the field against exact mesh queries within a trilinear bound derived from the cell
size and the surface's curvature; thin parts and open meshes left to the exact query or signed as
the exact query signs them; hair falling onto a breathing, bumpy body whose points are set every
frame stays outside through the field as through exact queries; the automatic choice, and the
USD attributes on a point-cached mesh."""

import numpy as np
import pytest
import warp as wp
from pxr import Sdf, UsdGeom, UsdPhysics, Vt
from mesh_shapes import uv_sphere
from usd_stages import add_curves, composed_samples, new_stage

import dftl_warp as dw
from dftl_warp import features as F
from dftl_warp.features.colliders.sdf import SDF_MIN_TRIANGLES, mesh_signed_distance

G = (0.0, -9.81, 0.0)
R0 = 0.08  # m, the body's mean radius
SQRT3 = np.sqrt(3.0)


def body_radius(u, t):
    """Radius (m) of the irregular body along unit directions ``u`` (N, 3) at time ``t`` (s): a
    smooth function of the direction (no kink at the poles), breathing by 2 mm, its bumps moving."""
    w = 2.0 * np.pi * 0.5 * t
    return (R0 + 0.002 * np.sin(2.0 * np.pi * t) + 0.003 * np.sin(3.0 * u[:, 0] + 2.0 * u[:, 1] + w)
            + 0.002 * np.cos(4.0 * u[:, 2] - u[:, 1]))


def body_points(directions, t):
    return directions * body_radius(directions, t)[:, None]


def implicit(x, t):
    """Zero on the body's surface (radial form)."""
    r = np.linalg.norm(x, axis=1)
    return r - body_radius(x / r[:, None], t)


def max_curvature(points, t, h=1e-4):
    """The largest |principal curvature| (1/m) of the body at surface ``points``: eigenvalues of the
    implicit function's Hessian projected on the tangent plane, over its gradient's length
    (central differences, float64)."""
    e = np.eye(3) * h
    grad = np.stack([(implicit(points + e[a], t) - implicit(points - e[a], t)) / (2 * h) for a in range(3)], 1)
    hess = np.empty((len(points), 3, 3))
    for a in range(3):
        for b in range(3):
            hess[:, a, b] = (implicit(points + e[a] + e[b], t) - implicit(points + e[a] - e[b], t)
                             - implicit(points - e[a] + e[b], t) + implicit(points - e[a] - e[b], t)) / (4 * h * h)
    g = np.linalg.norm(grad, axis=1)
    n = grad / g[:, None]
    proj = np.eye(3)[None] - n[:, :, None] * n[:, None, :]
    shape = proj @ hess @ proj / g[:, None, None]
    return float(np.abs(np.linalg.eigvalsh(shape)).max())


def radial_deviation(points, tris, t, per_side=6):
    """The largest radial distance (m) between the mesh's triangles (sampled on a barycentric grid)
    and the smooth body: a bound of their Hausdorff distance (the surface is star-shaped)."""
    a, b = np.meshgrid(np.arange(per_side + 1), np.arange(per_side + 1), indexing="ij")
    keep = a + b <= per_side
    w = np.stack([a[keep], b[keep], per_side - a[keep] - b[keep]], 1) / per_side
    tri = points[tris]
    samples = np.einsum("kw,twc->tkc", w, tri).reshape(-1, 3)
    r = np.linalg.norm(samples, axis=1)
    return float(np.abs(r - body_radius(samples / r[:, None], t)).max())


def field_bound(h, kappa, delta, depth):
    """Bound (m) of |trilinear field - exact mesh distance| in a cell whose corners are within
    ``depth`` of the surface: the field of the mesh is within ``delta`` (Hausdorff distance) of the
    smooth surface's, whose second derivatives are at most kappa / (1 - kappa depth) there; the
    trilinear error of a C2 function is at most h^2 / 8 sum_a |d_aa| (3 axes); float32 rounding
    of the node positions and distances (~1e-7 m here) added."""
    return 2.0 * delta + 3.0 * h * h / 8.0 * kappa / (1.0 - kappa * depth) + 2e-7


def one_collider(shape, device="cpu", widths=1e-4):
    """The Control's mesh colliders of a model with ``shape`` as its only collider."""
    model = dw.Model.from_strands(np.array([[0.0, 1.0, 0.0], [0.0, 1.01, 0.0]]), [2], widths=widths, device=device,
                                  features=[F.Colliders([shape])])
    return model.control().features.colliders.kind_data["meshes"]


def test_field_agrees_with_exact_mesh_distances_within_the_trilinear_bound():
    dirs, tris = uv_sphere(100, 200)  # 39600 triangles, edges ~2 mm
    pts = body_points(dirs, 0.0)
    h = 0.003
    meshes = one_collider(F.TriangleMesh(points=pts, indices=tris, sdf_cell=h))
    assert len(tris) >= SDF_MIN_TRIANGLES and 0 in meshes.fields.fields  # chosen automatically
    field = meshes.fields.fields[0]
    kappa = max_curvature(pts, 0.0)
    delta = 1.1 * radial_deviation(pts, tris, 0.0)
    assert 10 < kappa < 60 and delta < 5e-5  # an irregular body, finely meshed (sanity of the set-up)
    rng = np.random.default_rng(7)
    surface = pts[rng.integers(0, len(pts), 20000)]
    q = surface * (1.0 + rng.uniform(-1.0, 1.0, (len(surface), 1)) * (field.band - SQRT3 * h) / R0)
    exact, exact_n = mesh_signed_distance(meshes.meshes[0][1], q)
    state, d, n = meshes.fields.sample(0, q)
    reach = field.band - SQRT3 * h
    inside_reach = np.abs(exact) < reach - 1e-4
    answered = state == 1
    assert answered[inside_reach].mean() > 0.97  # the field answers (nearly) everywhere near a smooth body
    assert np.all(state[inside_reach] != 0)  # never "far" within its reach
    bound = field_bound(h, kappa, delta, np.abs(exact) + SQRT3 * h)
    error = np.abs(d - exact)
    assert np.all(error[answered] <= bound[answered]), float((error - bound)[answered].max())
    assert np.all(error[answered] <= field.tolerance)  # and within the tolerance its cells promise
    cos = np.sum(n * exact_n, axis=1)[answered]
    assert cos.min() > 0.97  # its gradient is the surface's normal
    print(f"\nfield vs exact: cell {h * 1e3:.1f} mm, {answered[inside_reach].mean():.4f} of the band answered, "
          f"largest error {error[answered].max() * 1e6:.1f} um (bound {bound[answered].min() * 1e6:.0f}-"
          f"{bound[answered].max() * 1e6:.0f} um, tolerance {field.tolerance * 1e6:.0f} um)")


def test_fields_of_several_colliders_share_the_arrays_and_deform_on_their_own():
    """Two mesh colliders with fields (device order after a sphere): each answers for its own
    mesh, and setting one's points rebuilds that one only."""
    dirs, tris = uv_sphere(60, 120)
    a = F.TriangleMesh(points=body_points(dirs, 0.0), indices=tris, sdf=True, sdf_cell=0.003)
    b = F.TriangleMesh(points=1.5 * body_points(dirs, 0.3), indices=tris, sdf=True, sdf_cell=0.004,
                       position=(0.5, 0.0, 0.0))
    model = dw.Model.from_strands(np.array([[0.0, 1.0, 0.0], [0.0, 1.01, 0.0]]), [2], widths=1e-4,
                                  features=[F.Colliders([F.Sphere(radius=0.1, position=(3.0, 0.0, 0.0)), b, a])])
    control = model.control()
    meshes = control.features.colliders.kind_data["meshes"]
    rng = np.random.default_rng(11)

    def worst_error(user, points):
        c, mesh = meshes.meshes[user]
        q = points[rng.integers(0, len(points), 4000)] * (1.0 + rng.uniform(-0.03, 0.03, (4000, 1)))
        state, d, _ = meshes.fields.sample(c, q)
        exact, _ = mesh_signed_distance(mesh, q)
        assert (state == 1).mean() > 0.97
        return np.abs(d - exact)[state == 1].max() / meshes.fields.fields[c].tolerance

    assert worst_error(1, b.points) < 1.0 and worst_error(2, a.points) < 1.0
    moved = body_points(dirs, 0.5)
    # placed there (start=moved: no motion within the frame, which a field follows only up to its band)
    control.features.set_mesh_points(2, moved, start=moved)
    assert worst_error(2, moved) < 1.0 and worst_error(1, b.points) < 1.0


def box_mesh(half):
    hx, hy, hz = half
    p = np.array([[x, y, z] for x in (-hx, hx) for y in (-hy, hy) for z in (-hz, hz)])
    quads = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    return p, np.array([t for a, b, c, d in quads for t in ((a, b, c), (a, c, d))])


def test_thin_plate_is_left_to_the_exact_query_and_hair_lands_on_it():
    """A 0.8 mm plate meshed with 12 triangles, forced through 2 mm cells, between two layers of
    nodes (y = 0 and 2 mm; the grid's nodes lie on multiples of the cell): the cells across it are
    EXACT (the corners below see the bottom face, those above the top one), the answered ones are
    exact (the field of one face is linear), and a strand falling onto it lands on top."""
    points, tris = box_mesh((0.1, 0.0004, 0.1))
    points = points + [0.0, 0.001, 0.0]
    shape = F.TriangleMesh(points=points, indices=tris, sdf=True, sdf_cell=0.002)
    assert shape.uses_sdf and len(tris) < SDF_MIN_TRIANGLES
    meshes = one_collider(shape)
    rng = np.random.default_rng(3)
    q = rng.uniform([-0.08, -0.003, -0.08], [0.08, 0.005, 0.08], (20000, 3))
    state, d, _ = meshes.fields.sample(0, q)
    exact, _ = mesh_signed_distance(meshes.meshes[0][1], q)
    across = np.abs(q[:, 1] - 0.001) < 0.0009
    assert np.all(state[across] == 2)
    answered = state == 1
    assert answered.mean() > 0.2 and np.abs(d - exact)[answered].max() < 1e-6
    n, width = 20, 0.001
    pts = np.stack([np.linspace(-0.05, 0.05, n), np.full(n, 0.03), np.zeros(n)], 1)
    model = dw.Model.from_strands(pts, [n], widths=width, features=[F.Colliders([shape])])
    top = 0.0014
    solver = dw.DFTLSolver(model, gravity=G)
    state_, control = solver.state(), model.control()
    lowest = np.inf
    for _ in range(24):
        for k in range(4):
            solver.step(state_, state_, control, 1 / 96, (k + 1) / 4)
            lowest = min(lowest, model.points_from_device(state_.positions)[:, 1].min())
    x = model.points_from_device(state_.positions)
    assert lowest > top + width / 2 - 1e-6  # never below the plate's top (plus the hair radius)
    assert np.sum(x[:, 1] < top + width) > n // 2  # it did land on it


def test_open_sheet_is_signed_as_the_exact_query_signs_it():
    """An open ground sheet: inside behind its faces, as the exact collider has it."""
    sheet = np.array([[-1.0, 0.0, -1.0], [1.0, 0.0, -1.0], [1.0, 0.0, 1.0], [-1.0, 0.0, 1.0]]) * 0.2
    meshes = one_collider(F.TriangleMesh(points=sheet, indices=[[0, 2, 1], [0, 3, 2]], sdf=True, sdf_cell=0.004))
    rng = np.random.default_rng(5)
    q = rng.uniform([-0.15, -0.006, -0.15], [0.15, 0.006, 0.15], (5000, 3))
    state, d, n = meshes.fields.sample(0, q)
    answered = state == 1
    assert answered.mean() > 0.9
    np.testing.assert_allclose(d[answered], q[answered, 1], atol=1e-6)
    assert np.all(n[answered, 1] > 0.999)


def drape(sdf: bool, directions, tris, frames=24, substeps=5, width=1e-3):
    """36 strands falling onto the breathing body (its points set every frame): the worst
    penetration of the contact distance over every substep, measured with the exact signed
    distance to the mesh the step saw, in hair radii; and the particles touching at the end."""
    n, spacing = 16, 0.006
    roots = [(x, 0.1, z) for x in np.linspace(-0.03, 0.03, 6) for z in np.linspace(-0.03, 0.03, 6)]
    pts = np.concatenate([np.array(r) + np.arange(n)[:, None] * spacing * np.array([1.0, 0.0, 0.0]) for r in roots])
    shape = F.TriangleMesh(points=body_points(directions, 0.0), indices=tris, sdf=sdf, sdf_cell=0.003)
    model = dw.Model.from_strands(pts, [n] * len(roots), widths=width, features=[F.Colliders([shape])])
    solver = dw.DFTLSolver(model, gravity=G)
    state, control = solver.state(), model.control()
    meshes = control.features.colliders.kind_data["meshes"]
    worst = 0.0
    for f in range(frames):
        control.features.set_mesh_points(0, body_points(directions, (f + 1) / 24))
        for k in range(substeps):
            solver.step(state, state, control, 1 / 24 / substeps, (k + 1) / substeps)
            d, _ = mesh_signed_distance(meshes.mesh_now(0), model.points_from_device(state.positions), 0.05)
            worst = max(worst, float((width / 2 - d).max()))
    touching = int(np.sum(d < width / 2 + 1e-4))
    return worst / (width / 2), touching, meshes


def test_hair_on_a_breathing_body_stays_outside_through_the_field_as_through_exact_queries():
    dirs, tris = uv_sphere(60, 120)  # 14160 triangles
    exact, touching_exact, _ = drape(False, dirs, tris)
    field, touching_field, meshes = drape(True, dirs, tris)
    assert 0 in meshes.fields.fields and touching_exact > 100 and touching_field > 100
    # the field's error at the surface bounds what it lets through (the mesh's radial deviation
    # from the smooth body and the curvature over the frames run)
    times = np.arange(0, 25, 4) / 24
    kappa = max(max_curvature(body_points(dirs, t), t) for t in times)
    delta = 1.1 * max(radial_deviation(body_points(dirs, t), tris, t, per_side=4) for t in times)
    h = 0.003
    bound = field_bound(h, kappa, delta, SQRT3 * h) / 0.0005  # in hair radii
    print(f"\nbreathing body: worst penetration of the contact distance {exact:.2g} hair radii through exact "
          f"queries, {field:.2g} through the field (bound {bound:.2g}; tolerance "
          f"{meshes.fields.fields[0].tolerance / 0.0005:.2g})")
    assert exact < 0.01
    assert field <= exact + bound


def test_automatic_choice_and_forcing():
    dirs, tris = uv_sphere(24, 48)  # 2208 triangles
    small = F.TriangleMesh(points=dirs * 0.1, indices=tris)
    assert not small.uses_sdf and F.TriangleMesh(points=dirs * 0.1, indices=tris, sdf=True).uses_sdf
    dirs, tris = uv_sphere(101, 100)  # 20000 triangles
    assert len(tris) >= SDF_MIN_TRIANGLES
    assert F.TriangleMesh(points=dirs * 0.1, indices=tris).uses_sdf
    assert not F.TriangleMesh(points=dirs * 0.1, indices=tris, sdf=False).uses_sdf
    with pytest.raises(ValueError, match="sdf_cell"):
        F.TriangleMesh(points=dirs * 0.1, indices=tris, sdf_cell=0.0)


def test_usd_point_cached_mesh_collides_through_its_field(tmp_path):
    """A Mesh prim with time-sampled points (breathing) and dftl:collisionSdf: read with the field's
    settings, its points set every frame; the hair never sinks into the mesh of the frame."""
    from dftl_warp.features.colliders import from_scene
    from dftl_warp.simulation.simulate import simulate_usd
    from dftl_warp.usd.read import read_scene

    dirs, tris = uv_sphere(40, 80)  # 6240 triangles: below the automatic choice
    stage = new_stage(tmp_path / "in.usda", start=1, end=12)
    mesh = UsdGeom.Mesh.Define(stage, "/World/Body")
    mesh.CreateFaceVertexCountsAttr(Vt.IntArray([3] * len(tris)))
    mesh.CreateFaceVertexIndicesAttr(Vt.IntArray([int(i) for i in tris.reshape(-1)]))
    frames = {f: body_points(dirs, (f - 1) / 24).astype(np.float32) for f in range(1, 13)}
    for f, p in frames.items():
        mesh.GetPointsAttr().Set(Vt.Vec3fArray.FromNumpy(p), f)
    UsdPhysics.CollisionAPI.Apply(mesh.GetPrim())
    mesh.GetPrim().CreateAttribute("dftl:collisionSdf", Sdf.ValueTypeNames.Bool, custom=True).Set(True)
    mesh.GetPrim().CreateAttribute("dftl:collisionSdfCellSize", Sdf.ValueTypeNames.Float, custom=True).Set(0.004)
    n = 12
    hair = np.concatenate([np.stack([np.linspace(0, 0.066, n) + x, np.full(n, 0.095), np.full(n, z)], 1)
                           for x in (-0.02, 0.0) for z in (-0.01, 0.01)])
    add_curves(stage, "/World/Hair", hair, [n] * 4, widths=0.001)
    stage.Save()
    scene = read_scene(tmp_path / "in.usda")
    (colliders,) = from_scene(scene, 1)
    (shape,) = colliders.shapes
    assert shape.sdf is True and shape.sdf_cell == pytest.approx(0.004) and shape.uses_sdf
    assert scene.colliders[0].points_sampler is not None  # the point cache is read
    out = tmp_path / "out.usdc"
    simulate_usd(tmp_path / "in.usda", out, substeps=8)
    samples = composed_samples(out, "/World/Hair")
    assert sorted(samples) == list(range(1, 13))
    worst, lowest = 0.0, np.inf
    for f, x in samples.items():
        body = wp.Mesh(points=wp.array(frames[f], dtype=wp.vec3), indices=wp.array(tris.reshape(-1).astype(np.int32),
                                                                                   dtype=wp.int32))
        d, _ = mesh_signed_distance(body, x, 0.05)
        worst = max(worst, float((0.0005 - d).max()))
        lowest = min(lowest, float(d.min()))
    times = np.arange(0, 12, 3) / 24
    kappa = max(max_curvature(body_points(dirs, t), t) for t in times)
    delta = 1.1 * max(radial_deviation(body_points(dirs, t), tris, t) for t in times)
    print(f"\nUSD point cache through the field: worst penetration {worst / 0.0005:.2g} hair radii at the "
          f"written frames (bound {field_bound(0.004, kappa, delta, SQRT3 * 0.004) / 0.0005:.2g})")
    assert lowest < 0.002  # the hair did reach the body ...
    assert worst <= field_bound(0.004, kappa, delta, SQRT3 * 0.004)  # ... and sank no deeper than the field errs


PLATE_DROP = """
import json, sys
import numpy as np
import warp as wp
from dftl_warp.kernels.features import mesh as mesh_kernels
mesh_kernels.COUNT_FIELD_TESTS = sys.argv[1] == "on"
import dftl_warp as dw
from dftl_warp import features as F
wp.config.quiet = True
half = (0.1, 0.0004, 0.1)
p = np.array([[x, y, z] for x in (-half[0], half[0]) for y in (-half[1], half[1]) for z in (-half[2], half[2])])
quads = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
tris = np.array([t for a, b, c, d in quads for t in ((a, b, c), (a, c, d))])
shape = F.TriangleMesh(points=p + [0.0, 0.001, 0.0], indices=tris, sdf=True, sdf_cell=0.002)
n = 20
pts = np.stack([np.linspace(-0.05, 0.05, n), np.full(n, 0.03), np.zeros(n)], 1)
model = dw.Model.from_strands(pts, [n], widths=0.001, features=[F.Colliders([shape])])
solver = dw.DFTLSolver(model, gravity=(0.0, -9.81, 0.0))
state, control = solver.state(), model.control()
for _ in range(24):
    for k in range(4):
        solver.step(state, state, control, 1 / 96, (k + 1) / 4)
print(json.dumps(control.features.colliders.kind_data["meshes"].fields.tests()))
"""


def test_field_tests_are_counted_by_outcome_only_when_asked():
    """The diagnostic count of a field's tests (``kernels.features.mesh.COUNT_FIELD_TESTS``, in a
    process of its own as it must be set before kernels are built): a strand dropped onto the thin
    plate above has every free particle tested every substep; falling through free air it is
    answered by one sample, approaching the plate by a trace, and once it rests on the plate (most
    of the run) its paths end in the EXACT cells across the plate and go to the exact query. Off
    (the default), the kernels count nothing."""
    import json
    import subprocess
    import sys

    from dftl_warp.kernels.features.sdf import EXACT_FROM, WHY_EXACT

    def run(flag):
        done = subprocess.run([sys.executable, "-c", PLATE_DROP, flag], capture_output=True, text=True)
        assert done.returncode == 0, done.stderr[-2000:]
        return json.loads(done.stdout.strip().splitlines()[-1])

    on, off = run("on"), run("off")
    assert set(on) == set(WHY_EXACT) and sum(off.values()) == 0
    # every free particle is tested at least once a substep (a touched one again, up to the rounds)
    assert 19 * 24 * 4 <= sum(on.values()) <= 2 * 19 * 24 * 4
    assert on[WHY_EXACT[0]] > 0 and on["answered by the field: traced along the path"] > 0
    resting = on["exact query: the path's end in a cell the field cannot answer"]
    assert resting == max(on.values()) and resting > sum(on[w] for w in WHY_EXACT[:EXACT_FROM])


def test_the_continuous_test_through_the_field_never_misses_a_crossing_the_mesh_has():
    """Short fast paths near a sphere mesh, many of them grazing it: the field's continuous test
    (the ends' clearances, the over-relaxed trace) reports contact, or leaves the path to the exact
    query, on every path whose closest approach to the mesh (sampled along it against the exact
    mesh distance) lies below the contact distance by more than the field's tolerance; and it
    never reports contact on a path that stays clear of it by as much."""
    from dftl_warp.kernels.features.sdf import EXACT_FROM, SdfGrid, collide_sdf_func

    sphere = 0.01
    dirs, tris = uv_sphere(60, 120)
    meshes = one_collider(F.TriangleMesh(points=sphere * dirs, indices=tris, sdf=True))
    fields = meshes.fields
    tolerance = fields.fields[0].tolerance
    collide = collide_sdf_func(wp.float32)

    @wp.kernel
    def continuous_test(grids: wp.array(dtype=SdfGrid), brick_map: wp.array(dtype=wp.int32),
                        values: wp.array(dtype=wp.float32), cells: wp.array(dtype=wp.uint8),
                        starts: wp.array(dtype=wp.vec3), ends: wp.array(dtype=wp.vec3), radius: float,
                        touched: wp.array(dtype=wp.int32), why: wp.array(dtype=wp.int32)):
        i = wp.tid()
        pose = wp.transform_identity(dtype=float)
        y, hit, w, taken = collide(ends[i], starts[i], starts[i], 0.01, True, radius, pose, pose, pose, grids[0],
                                     brick_map, values, cells, 0.0, 0.0)
        touched[i] = wp.where(hit, 1, 0)
        why[i] = w

    rng = np.random.default_rng(5)
    n, radius = 20000, 5e-5
    normal = rng.normal(size=(n, 3))
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    tangent = np.cross(normal, rng.normal(size=(n, 3)))
    tangent /= np.linalg.norm(tangent, axis=1, keepdims=True)
    length = rng.uniform(0.0005, 0.01, n)
    # half of them start clear of the surface, mostly along it, some toward it; the other half are
    # chords 6-20 mm long through the sphere's cap, their middle up to 0.1 mm inside, both ends
    # outside (a step too long would jump across the cap)
    half = n // 2
    slope = rng.uniform(-0.4, 0.2, half)[:, None]
    direction = tangent[:half] + slope * normal[:half]
    direction /= np.linalg.norm(direction, axis=1, keepdims=True)
    starts = normal[:half] * (sphere + radius + 1e-5 + rng.uniform(0.0, 0.002, half))[:, None]
    ends = starts + direction * length[:half, None]
    middle = normal[half:] * (sphere - rng.uniform(0.0, 0.0001, n - half))[:, None]
    chord = tangent[half:] * rng.uniform(0.003, 0.01, (n - half, 1))
    starts, ends = np.concatenate([starts, middle - chord]), np.concatenate([ends, middle + chord])
    t = np.linspace(0.0, 1.0, 401)
    along = starts[:, None] + t[None, :, None] * (ends - starts)[:, None]
    exact, _ = mesh_signed_distance(meshes.meshes[0][1], along.reshape(-1, 3))
    closest = exact.reshape(n, -1).min(axis=1)
    touched = wp.zeros(n, dtype=wp.int32)
    why = wp.zeros(n, dtype=wp.int32)
    wp.launch(continuous_test, dim=n, inputs=[fields.grids, fields.brick_map, fields.values, fields.cells,
                                              wp.array(starts, dtype=wp.vec3), wp.array(ends, dtype=wp.vec3),
                                              radius], outputs=[touched, why])
    touched, why = touched.numpy() == 1, why.numpy()
    answered = why < EXACT_FROM
    slack = tolerance + np.linalg.norm(ends - starts, axis=1).max() / 400
    # paths from outside the contact distance (a particle in contact or inside is not traced)
    outside = exact.reshape(n, -1)[:, 0] > radius + slack
    crossing = outside & (closest < radius - slack)
    clear = outside & (closest > radius + slack)
    assert crossing.sum() > 3000 and clear.sum() > 3000 and answered[outside].mean() > 0.95, np.bincount(why)
    print(f"\n{crossing.sum()} crossing paths ({(crossing & answered).sum()} answered by the field), "
          f"{clear.sum()} clear ({(clear & answered).sum()}); outcomes {np.bincount(why, minlength=10).tolist()}")
    assert np.all(touched[crossing & answered])          # never a missed crossing
    assert not np.any(touched[clear & answered])         # never a contact that is not there
