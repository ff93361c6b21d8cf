"""Optional features: colliders, root binding, wind and drag, hair-hair, shape retention, and the
specialization of the step to exactly the features a scene has. Each test measures behaviour."""

import numpy as np
import pytest
import warp as wp

import dftl_warp as dw
from dftl_warp import features as F
from dftl_warp.kernels.solvers.ftl import bare_step_kernel
from dftl_warp.kernels.solvers.step import step_kernel

from conftest import segment_lengths

G = (0.0, -9.81, 0.0)
FPS = 24


def generated_source(kernel) -> str:
    """The C++ Warp generates for ``kernel``'s module on the CPU, without its ``//`` comment lines
    (they name the Python source files, whose paths hold the checkout's folder names)."""
    from warp._src.context import ModuleBuilder

    module = kernel.module
    code = ModuleBuilder(module, module.options, target="cpu").codegen("cpu")
    return "\n".join(line for line in code.splitlines() if not line.lstrip().startswith("//"))


def box_mesh(half):
    """Closed box mesh (8 points, 12 outward-facing triangles) of half extents ``half``."""
    hx, hy, hz = half
    p = np.array([[x, y, z] for x in (-hx, hx) for y in (-hy, hy) for z in (-hz, hz)])
    quads = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    return p, np.array([t for a, b, c, d in quads for t in ((a, b, c), (a, c, d))])


def run_frames(model, frames, substeps, before_frame=None, after_substep=None, **solver_options):
    solver = dw.DFTLSolver(model, gravity=G, **solver_options)
    state, control = solver.state(), model.control()
    for f in range(frames):
        if before_frame is not None:
            before_frame(control, f)
        for k in range(substeps):
            solver.step(state, state, control, 1.0 / FPS / substeps, (k + 1) / substeps)
            if after_substep is not None:
                after_substep(state, f, k)
    return solver, state


# -- specialization ----------------------------------------------------------------------------------


def test_gravity_only_scene_runs_the_bare_kernel():
    pts = np.stack([np.arange(6) * 0.02, np.zeros(6), np.zeros(6)], 1)
    tri = np.array([[0.0, 0.0, -1.0], [1.0, 0.0, 1.0], [-1.0, 0.0, 1.0]])
    plain = dw.Model.from_strands(pts, [6])
    empty = dw.Model.from_strands(pts, [6], features=[])
    # a root binding is per-frame work only: the step stays the bare one
    bound = dw.Model.from_strands(pts, [6], features=[F.RootBinding(tri, [[0, 1, 2]])])
    bare = bare_step_kernel(wp.float32, "prior")
    for model in (plain, empty, bound):
        solver = dw.DFTLSolver(model, gravity=G)
        assert model.feature_flags == frozenset()
        assert solver._kernel is bare and solver._features is None
    assert step_kernel(wp.float32, "prior", frozenset()) is bare
    assert step_kernel(wp.float32, "prior") is bare
    assert bare.module.hash_module() == dw.DFTLSolver(bound)._kernel.module.hash_module()
    # and the trajectories are the bare ones, bit for bit
    runs = []
    for model in (plain, empty):
        solver = dw.DFTLSolver(model, gravity=G)
        state, control = solver.state(), model.control()
        solver.advance(state, control, 1e-3, 50)
        runs.append(state.positions.numpy())
    assert np.array_equal(runs[0], runs[1])


def test_colliders_without_wind_compile_no_wind_code():
    pts = np.stack([np.arange(4) * 0.02, np.ones(4), np.zeros(4)], 1)
    model = dw.Model.from_strands(pts, [4], features=[F.Colliders([F.Sphere(radius=0.5)])])
    solver = dw.DFTLSolver(model, gravity=G)
    assert model.feature_flags == {"spheres"}
    source = generated_source(solver._kernel)
    assert "collide_sphere" in source
    for absent in ("wind", "curlnoise", "drag", "grid", "shape", "collide_capsule", "collide_box", "mesh_query"):
        assert absent not in source, absent
    # the same scene with wind compiles it into its velocity pass (kernels/features/air_grid.py); its
    # sweep is this scene's, colliders only
    windy = dw.Model.from_strands(pts, [4], features=[F.Colliders([F.Sphere(radius=0.5)]), F.Drag(1.0),
                                                       F.Wind(velocity=(1.0, 0.0, 0.0))])
    windy_solver = dw.DFTLSolver(windy, gravity=G)
    assert windy_solver._kernel is solver._kernel
    assert windy_solver._features.pass_flags == {"drag", "wind"}
    assert "wind" in generated_source(windy_solver._features._pass_kernel)
    assert "collide_sphere" not in generated_source(windy_solver._features._pass_kernel)


# -- colliders ---------------------------------------------------------------------------------------


def test_drape_over_sphere_hit_by_moving_capsule():
    """Strands fall onto a sphere, drape, then a capsule sweeps through them at 1 m/s."""
    sphere_r, cap_r, cap_half, width, n = 0.1, 0.03, 0.1, 0.002, 40
    pts = np.concatenate([np.stack([np.full(n, x), np.full(n, sphere_r + 0.005), np.arange(n) * 0.01 - 0.02], 1)
                          for x in np.linspace(-0.04, 0.04, 9)])
    counts = np.full(9, n)
    cap_start = np.array([0.3, -0.17, 0.11])

    def cap_centre(t):
        return cap_start + np.array([-1.0, 0.0, 0.0]) * max(t - 1.0, 0.0)

    colliders = F.Colliders([F.Sphere(radius=sphere_r), F.Capsule(radius=cap_r, half_height=cap_half, axis="Z",
                                                                    position=cap_start)])
    model = dw.Model.from_strands(pts, counts, widths=width, features=[colliders])
    substeps = 10
    worst = {"sphere": 0.0, "capsule": 0.0, "stretch": 0.0, "touching": 0}
    rest = segment_lengths(pts, counts)

    def before_frame(control, f):
        ident = [0, 0, 0, 0, 0, 0, 1]
        control.features.set_collider_poses([ident, [*cap_centre(f / FPS), 0, 0, 0, 1]],
                                            [ident, [*cap_centre((f + 1) / FPS), 0, 0, 0, 1]])

    def after_substep(state, f, k):
        x = model.points_from_device(state.positions)
        t = (f + (k + 1) / substeps) / FPS
        worst["sphere"] = max(worst["sphere"], (sphere_r + width / 2 - np.linalg.norm(x, axis=1)).max())
        q = x - cap_centre(t)
        axial = np.clip(q[:, 2], -cap_half, cap_half)
        d = np.linalg.norm(q - axial[:, None] * [0, 0, 1], axis=1)
        worst["capsule"] = max(worst["capsule"], (cap_r + width / 2 - d).max())
        worst["touching"] = max(worst["touching"], int(np.sum(d < cap_r + width)))
        worst["stretch"] = max(worst["stretch"], np.abs(segment_lengths(x, counts) / rest - 1).max())

    run_frames(model, 60, substeps, before_frame, after_substep)
    assert worst["touching"] > 10  # the capsule did plough through the hair
    assert worst["sphere"] < 0.02 * sphere_r
    assert worst["capsule"] < 0.05 * cap_r
    assert worst["stretch"] < 1e-3


def throw_down(slab, height, n=20, width=0.002):
    """A straight strand of ``n`` points along x at ``height`` (m), its non-root points thrown down
    at 10 m/s onto ``slab``, one substep per frame at 24 fps (0.42 m per step) for a second:
    (rest points, final points, the lowest height any point reached)."""
    pts = np.stack([np.linspace(-0.3, 0.3, n), np.full(n, height), np.zeros(n)], 1)
    model = dw.Model.from_strands(pts, [n], widths=width, features=[F.Colliders([slab])])
    solver = dw.DFTLSolver(model, gravity=G)
    state, control = solver.state(), model.control()
    v = np.zeros_like(pts)
    v[1:, 1] = -10.0
    state.write("velocities", model.points_to_device(v, relative=False))
    lowest = np.inf
    for _ in range(FPS):
        solver.step(state, state, control, 1.0 / FPS)
        lowest = min(lowest, model.points_from_device(state.positions)[:, 1].min())
    return pts, model.points_from_device(state.positions), lowest


def thin_slab(shape):
    """A 2 cm slab (top at y = 0.01) as an analytic box or a triangle mesh."""
    if shape == "box":
        return F.Box(half_extents=(1.0, 0.01, 1.0))
    points, indices = box_mesh((1.0, 0.01, 1.0))
    return F.TriangleMesh(points=points, indices=indices)


def test_fast_strand_does_not_tunnel_through_a_thin_mesh():
    """10 m/s onto a 2 cm slab, one substep per frame at 24 fps (0.42 m per step)."""
    n, width = 20, 0.002
    pts, x, lowest = throw_down(thin_slab("mesh"), 0.3, n, width)
    assert lowest > 0.01 + width / 2 - 1e-4  # never below the slab's top (plus the hair radius)
    assert np.sum(x[:, 1] < 0.02) > n // 3  # it did land on the slab
    assert np.abs(segment_lengths(x, [n]) / np.linalg.norm(pts[1] - pts[0]) - 1).max() < 1e-3


@pytest.mark.parametrize("shape", ["box", "mesh"])
def test_strand_resting_on_a_thin_slab_is_not_pushed_through_it(shape):
    """A strand lying on a 2 cm slab, in contact, then thrown down at 10 m/s, one substep per frame
    (0.42 m per step): a path that starts in contact is left to the projection only when it ends
    inside, nearest the face it crossed (resting contact, docs/features.md), so this one is still
    stopped on the slab's top."""
    width = 0.002
    _, _, lowest = throw_down(thin_slab(shape), 0.01 + width / 2, width=width)
    assert lowest > 0.01 + width / 2 - 1e-4  # never below the slab's top (plus the hair radius)


def test_friction_slows_a_strand_sliding_on_a_tilted_box():
    theta = np.radians(20.0)  # tan = 0.36
    rot = [0.0, 0.0, np.sin(-theta / 2), np.cos(-theta / 2)]
    c, s = np.cos(-theta), np.sin(-theta)
    world = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
    n, r, half_y = 15, 0.001, 0.05
    # lying across the slope, root held: it swings down the slope like a pendulum
    pts = np.stack([np.zeros(n), np.full(n, half_y + r), np.arange(n) * 0.02], 1) @ world.T
    moved = {}
    for mu in (0.0, 0.15, 0.3, 0.5):
        box = F.Box(half_extents=(1.0, half_y, 1.0), rotation=rot, friction=mu)
        model = dw.Model.from_strands(pts, [n], widths=2 * r, features=[F.Colliders([box])])
        _, state = run_frames(model, 12, 10)
        x = model.points_from_device(state.positions)
        moved[mu] = np.linalg.norm(x - pts, axis=1).mean()
        assert ((x @ world)[:, 1] - half_y - r).min() > -1e-5  # on the surface, not in it
    assert moved[0.0] > moved[0.15] > moved[0.3] > 0.01
    assert moved[0.5] < 1e-5  # friction beyond tan(20 deg) holds it still


# -- roots on a deforming mesh -------------------------------------------------------------------------


def test_roots_follow_a_deforming_mesh():
    mesh_pts = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 1.0]])
    tris = np.array([[0, 2, 1], [1, 2, 3]])
    roots = np.array([[0.2, 0.0, 0.3], [0.7, 0.0, 0.8]])
    pts = np.concatenate([r + np.arange(5)[:, None] * [0.0, -0.05, 0.0] for r in roots])
    model = dw.Model.from_strands(pts, [5, 5], features=[F.RootBinding(mesh_pts, tris)])
    solver = dw.DFTLSolver(model, gravity=G)
    state, control = solver.state(), model.control()
    for f in range(5):
        bent = mesh_pts + [0.0, 0.0, 0.0] + np.outer(mesh_pts[:, 0], [0.0, 0.1 * (f + 1), 0.0])
        moved = bent + [0.05 * (f + 1), 0.0, 0.0]
        control.bind_roots(moved)
        solver.advance(state, control, 1.0 / 240, 10)
    x = model.points_from_device(state.positions)
    # a point's barycentric weights are affine-invariant: the root is where the map sends it
    expected = roots + np.outer(roots[:, 0], [0.0, 0.5, 0.0]) + [0.25, 0.0, 0.0]
    assert np.abs(x[[0, 5]] - expected).max() < 1e-6


# -- air ------------------------------------------------------------------------------------------------


def test_wind_deflects_a_hanging_strand_downwind():
    n, drag = 20, 2.0
    pts = np.stack([np.zeros(n), -np.arange(n) * 0.01, np.zeros(n)], 1)
    for wind in ((2.0, 0.0, 0.0), (0.0, 0.0, -3.0)):
        model = dw.Model.from_strands(pts, [n], features=[F.Drag(drag), F.Wind(velocity=wind)])
        _, state = run_frames(model, 48, 10, before_frame=lambda c, f: c.features.set_frame_time(f / FPS, (f + 1) / FPS))
        tip = model.points_from_device(state.positions)[-1] - pts[0]
        w = np.asarray(wind)
        sideways = tip - tip @ [0, 1, 0] * np.array([0, 1, 0])
        assert sideways @ w / np.linalg.norm(w) > 0.5 * np.linalg.norm(sideways) > 0.03
        # a uniformly dragged chain hangs at atan(drag |w| / g) from the vertical
        angle = np.arctan2(np.linalg.norm(sideways), -tip[1])
        assert angle == pytest.approx(np.arctan(drag * np.linalg.norm(w) / 9.81), abs=np.radians(3))


def test_drag_damps_a_swinging_strand():
    n = 20
    pts = np.stack([np.arange(n) * 0.01, np.zeros(n), np.zeros(n)], 1)
    energy = {}
    for name, feats in (("still air", None), ("drag", [F.Drag(2.0)])):
        model = dw.Model.from_strands(pts, [n], features=feats)
        speeds = []
        run_frames(model, 48, 10, after_substep=lambda st, f, k: speeds.append(
            np.square(st.velocities.numpy()).sum()) if f >= 24 else None)
        energy[name] = np.mean(speeds)
    assert energy["drag"] < 0.5 * energy["still air"]


# -- hair-hair ------------------------------------------------------------------------------------------


def test_repulsion_makes_a_dense_bundle_occupy_more_volume():
    """A bundle at rest swells under the repulsion of all its density (threshold 0)."""
    rng = np.random.default_rng(0)
    n, side, spacing = 20, 7, 0.002
    strands = []
    for i in range(side):
        for j in range(side):
            d = np.array([1.0, 0.0, 0.0]) + rng.normal(scale=0.05, size=3)
            strands.append([i * spacing, 0.0, j * spacing] + np.arange(n)[:, None] * 0.01 * d / np.linalg.norm(d))
    pts, counts = np.concatenate(strands), np.full(side * side, n)
    volume = {}
    # 50 m/s^2 per unit density relative to the bundle's at rest: the push of 20 per particle per
    # node of the grid's first form (2.5 particles per node at rest)
    for repulsion in (0.0, 50.0):
        model = dw.Model.from_strands(pts, counts,
                                      features=[F.HairHair(cell_size=0.005, friction=2.0, repulsion=repulsion,
                                                           threshold=0.0)])
        _, state = run_frames(model, 48, 10)
        x = model.points_from_device(state.positions)
        volume[repulsion] = np.sqrt(np.linalg.det(np.cov(x.T)))  # ~ the bundle's volume
        assert np.abs(segment_lengths(x, counts) / 0.01 - 1).max() < 1e-5
    assert volume[50.0] > 3.0 * volume[0.0]


# -- shape retention ------------------------------------------------------------------------------------


def curl_radius(x, quarter):
    """1 / median curvature of the circles through points a quarter turn apart (m)."""
    a, b, c = x[: -2 * quarter], x[quarter:-quarter], x[2 * quarter:]
    area2 = np.linalg.norm(np.cross(b - a, c - a), axis=1)
    sides = np.linalg.norm(b - a, axis=1) * np.linalg.norm(c - b, axis=1) * np.linalg.norm(a - c, axis=1)
    return 1.0 / np.median(2.0 * area2 / sides)


def test_bad_feature_input_is_refused():
    pts = np.stack([np.arange(3) * 0.1, np.zeros(3), np.zeros(3)], 1)
    with pytest.raises(ValueError, match="add a Drag"):
        dw.Model.from_strands(pts, [3], features=[F.Wind(velocity=(1, 0, 0))])
    with pytest.raises(ValueError, match="given twice"):
        dw.Model.from_strands(pts, [3], features=[F.Drag(1.0), F.Drag(2.0)])
    with pytest.raises(ValueError, match="radius must be > 0"):
        F.Sphere(radius=0.0)
    with pytest.raises(ValueError, match="indices reference points"):
        F.TriangleMesh(points=np.zeros((3, 3)), indices=[[0, 1, 3]])
    with pytest.raises(ValueError, match="one per strand"):
        dw.Model.from_strands(pts, [3], features=[F.Drag([1.0, 2.0])])


@pytest.mark.parametrize("precision,correction", [("float64", "posterior"), ("float32", "prior")])
def test_all_features_together_keep_lengths(precision, correction):
    """Every feature at once, both precisions and correction forms: finite, inextensible, outside."""
    rng = np.random.default_rng(3)
    n, strands = 12, 16
    roots = np.stack([rng.uniform(-0.05, 0.05, strands), np.full(strands, 0.13), rng.uniform(-0.05, 0.05, strands)], 1)
    pts = np.concatenate([r + np.arange(n)[:, None] * [0.01, 0.0, 0.0] for r in roots])
    counts = np.full(strands, n)
    mesh_pts, mesh_tris = box_mesh((0.3, 0.01, 0.3))
    feats = [
        F.Colliders([F.Sphere(radius=0.1, friction=0.2), F.Capsule(radius=0.02, half_height=0.05, position=(0, 0, 0.15)),
                     F.Box(half_extents=(0.05, 0.05, 0.05), position=(0.12, 0.0, 0.0)),
                     F.TriangleMesh(points=mesh_pts, indices=mesh_tris, position=(0.0, -0.2, 0.0))]),
        F.Drag(0.5), F.Wind(velocity=[[0.0, 0.5, 0.0, 0.0], [1.0, 0.0, 0.0, 1.0]], noise_amplitude=0.3),
        F.HairHair(cell_size=0.01),
    ]
    model = dw.Model.from_strands(pts, counts, widths=0.002, precision=precision, features=feats)
    assert model.feature_flags == {"spheres", "capsules", "boxes", "meshes", "drag", "wind", "wind_noise",
                                   "hair_hair"}
    solver = dw.DFTLSolver(model, gravity=G, correction=correction)
    state, control = solver.state(), model.control()
    for f in range(24):
        control.features.set_frame_time(f / FPS, (f + 1) / FPS)
        solver.advance(state, control, 1.0 / FPS / 5, 5)
    x = model.points_from_device(state.positions)
    assert np.isfinite(x).all()
    assert np.abs(segment_lengths(x, counts) / 0.01 - 1).max() < (1e-10 if precision == "float64" else 1e-5)
    assert (np.linalg.norm(x, axis=1) > 0.1 + 0.001 - 0.002).all()  # outside the sphere (2% of its radius)
    assert x[:, 1].min() > -0.2 + 0.01  # above the ground slab


def test_dftl_attributes_map_to_features():
    from dftl_warp.features import features_from_attributes

    scene = {"dftl:drag": 1.5, "dftl:wind": [[0.0, 1.0, 0.0, 0.0], [2.0, 3.0, 0.0, 0.0]], "dftl:windNoise": 0.2,
             "dftl:hairHair": True, "dftl:hairHairRepulsion": 8.0}
    curves = [{"path": "/a"}, {"path": "/b", "dftl:drag": 0.0}]
    feats = features_from_attributes(scene, curves, [2, 3], mean_segment=0.01)
    by_type = {type(f).__name__: f for f in feats}
    assert set(by_type) == {"Drag", "Wind", "HairHair"}
    assert list(by_type["Drag"].rate) == [1.5, 1.5, 0.0, 0.0, 0.0]
    assert np.allclose(by_type["Wind"].at(1.0), [2.0, 0.0, 0.0])
    assert by_type["Wind"].flags == {"wind", "wind_noise"}
    assert by_type["HairHair"].cell_size == pytest.approx(0.04) and by_type["HairHair"].repulsion == 8.0
    assert features_from_attributes({}, [{}], [4]) == []
    with pytest.raises(ValueError, match="/b: dftl:drag = -1.0: must be"):
        features_from_attributes({}, [{}, {"path": "/b", "dftl:drag": -1.0}], [1, 1])
    with pytest.raises(ValueError, match="author dftl:drag"):
        features_from_attributes({"dftl:wind": (1.0, 0.0, 0.0)}, [{}], [1])


def test_memory_estimate_counts_the_features():
    from dftl_warp.features import memory_estimate

    pts = np.stack([np.arange(10) * 0.01, np.zeros(10), np.zeros(10)], 1)
    bare = memory_estimate(dw.Model.from_strands(pts, [10]))
    # State 36 B + rest length 4 B per particle, strand tables 12 B + root rest/targets 36 B
    assert bare["bytes_per_strand"] == 10 * 40 + 48 and bare["feature_bytes_per_strand"] == 0
    dragged = memory_estimate(dw.Model.from_strands(pts, [10], features=[F.Drag(0.5)]))
    # the drag rate, and the velocity pass's output: a velocity per particle (as the solver allocates)
    assert dragged["feature_bytes_per_strand"] == 4 + 10 * 12
    model = dw.Model.from_strands(pts, [10], features=[F.Drag(0.5)])
    assert dw.DFTLSolver(model)._features.pass_output.capacity == 10 * 12
    grid = memory_estimate(dw.Model.from_strands(pts, [10], features=[F.HairHair(cell_size=0.01)]))
    assert grid["fixed_feature_bytes"] > 0 and grid["feature_bytes_per_strand"] == 10 * 12
    # rebuilt every few substeps, the grid keeps the momentum's own density beside the density
    every = dw.Model.from_strands(pts, [10], features=[F.HairHair(cell_size=0.01, splat_interval=4)])
    assert memory_estimate(every)["fixed_feature_bytes"] == grid["fixed_feature_bytes"] * 5 // 4
    arrays = dw.DFTLSolver(every)._features._grid.arrays
    assert arrays["mass"].capacity == arrays["density"].capacity
