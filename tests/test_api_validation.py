"""Python API argument checks: solver options (unknown names, types, ranges), control inputs
(non-finite points and poses, zero quaternions), feature constructors and Model.from_strands."""

import numpy as np
import pytest

import dftl_warp as dw
from dftl_warp import features as F

NAN, INF = float("nan"), float("inf")


def _chain(n=6, x=0.0):
    return np.c_[np.full(n, x), -np.arange(n) * 0.01, np.zeros(n)]


@pytest.fixture(scope="module")
def model():
    return dw.Model.from_strands(_chain(), [6], widths=1e-4, device="cpu")


@pytest.fixture(scope="module")
def model64():
    return dw.Model.from_strands(_chain(), [6], widths=1e-4, device="cpu", precision="float64")


# -- 1. unknown solver options ---------------------------------------------------------------------


@pytest.mark.parametrize("solver, kw, hint", [
    ("dftl", {"dampnig": 0.2}, "damping"),
    ("elastic", {"youngs_modulu": 1.0}, "youngs_modulus"),
    ("elastic", {"gravitiy": (0, 0, 0)}, "gravity"),
])
def test_unknown_solver_option_is_a_typeerror_with_a_suggestion(model, solver, kw, hint):
    name = next(iter(kw))
    with pytest.raises(TypeError, match=rf"unknown keyword '{name}'.*did you mean '{hint}'"):
        dw.make_solver(model, solver, **kw)


def test_known_options_of_other_solvers_are_still_dropped(model):
    assert dw.make_solver(model, "pbd", iterations=3, damping=1.0, correction="prior").iterations == 3
    with pytest.warns(UserWarning, match="iterations") as caught:   # dropped, and said (tests/test_api_audit.py)
        assert isinstance(dw.make_solver(model, "dftl", iterations=3), dw.DFTLSolver)
    assert len(caught) == 1


# -- 2. option types and ranges ----------------------------------------------------------------------


@pytest.mark.parametrize("solver, kw, fragment", [
    ("reference", {"tolerance": 0}, "tolerance"),
    ("reference", {"tolerance": -1}, "tolerance"),
    ("reference", {"tolerance": NAN}, "tolerance"),
    ("reference", {"max_iterations": 0}, "max_iterations"),
    ("reference", {"max_iterations": 2.5}, "max_iterations"),
    ("reference", {"accept": -1.0}, "accept"),
    ("reference", {"frame_iterations": 0}, "frame_iterations"),
    ("pbd", {"iterations": 2.5}, "iterations"),
    ("pbd", {"iterations": 0}, "iterations"),
    ("elastic", {"inverse_statics": "no"}, "inverse_statics"),
    ("elastic", {"stiffness_scale": [1.0, 2.0]}, "stiffness_scale"),
    ("rattle", {"fallback": "bogus"}, "fallback"),
    ("rattle", {"fallback": INF}, "fallback"),
    ("rattle", {"newton_iterations": 1.5}, "newton_iterations"),
    ("rattle", {"max_halvings": 11}, "max_halvings"),
    ("rattle", {"on_chip": "yes"}, "on_chip"),
])
def test_solver_option_values_are_checked(model, model64, solver, kw, fragment):
    m = model64 if solver == "reference" else model
    with pytest.raises(ValueError, match=fragment):
        dw.make_solver(m, solver, **kw)


def test_valid_reference_options_still_build(model64):
    s = dw.make_solver(model64, "reference", tolerance=1e-12, max_iterations=5)
    assert (s.tolerance, s.max_iterations) == (1e-12, 5)


# -- 3. control inputs -------------------------------------------------------------------------------


_SCALP = np.array([[-1.0, 0.0, -1.0], [1.0, 0.0, -1.0], [0.0, 0.0, 1.0]])
_MESH = np.array([[-1.0, -0.2, -1.0], [1.0, -0.2, -1.0], [0.0, -0.2, 1.0]])


@pytest.fixture
def featured():
    pts = np.concatenate([_chain(), _chain(x=0.05)])
    m = dw.Model.from_strands(pts, [6, 6], widths=1e-4, device="cpu", features=[
        F.Colliders([F.Sphere(radius=0.01, position=(0, -1, 0)), F.TriangleMesh(points=_MESH, indices=[0, 2, 1])]),
        F.RootBinding(_SCALP, [0, 1, 2]), F.Drag(1.0), F.Wind(velocity=(1.0, 0, 0))])
    return dw.DFTLSolver(m), m.control()


def test_bind_roots_refuses_non_finite_points(featured):
    _, c = featured
    bad = _SCALP.copy()
    bad[2, 1] = NAN
    with pytest.raises(ValueError, match=r"root binding mesh points \(start\): row 2 is not finite"):
        c.bind_roots(bad, _SCALP)
    bad[2, 1] = INF
    with pytest.raises(ValueError, match=r"root binding mesh points \(end\): row 2 is not finite"):
        c.bind_roots(_SCALP, bad)


def test_collider_poses_refuse_non_finite_and_zero_quaternions(featured):
    _, c = featured
    poses = np.array([[0, 0, 0, 0, 0, 0, 1.0]] * 2)
    bad = poses.copy()
    bad[1, 0] = NAN
    with pytest.raises(ValueError, match=r"collider poses \(start\): row 1 is not finite"):
        c.features.set_collider_poses(bad, poses)
    zero = poses.copy()
    zero[0, 3:] = 0.0
    with pytest.raises(ValueError, match=r"collider poses \(end\): row 0 has a zero-length quaternion"):
        c.features.set_collider_poses(poses, zero)
    c.features.set_collider_poses(poses * [1, 1, 1, 1, 1, 1, 2.0])  # non-unit: normalised, accepted


def test_mesh_points_refuse_non_finite(featured):
    _, c = featured
    bad = _MESH.copy()
    bad[1, 0] = INF
    with pytest.raises(ValueError, match=r"mesh collider 1 points: row 1 is not finite"):
        c.features.set_mesh_points(1, bad)


def test_colliders_without_shapes_warn_that_they_do_nothing():
    with pytest.warns(UserWarning, match="Colliders has no shapes: the hair collides with nothing"):
        empty = F.Colliders([])
    model = dw.Model.from_strands(np.array([[0.0, 0, 0], [0, -0.01, 0]]), [2], features=[empty])
    assert model.feature_flags == frozenset()


def test_frame_time_and_wind_refuse_non_finite(featured):
    _, c = featured
    with pytest.raises(ValueError, match="set_frame_time: start"):
        c.features.set_frame_time(NAN, 1.0)
    with pytest.raises(ValueError, match="set_frame_time: end 0.5 s is before start 1.0 s"):
        c.features.set_frame_time(1.0, 0.5)
    c.features.set_frame_time(1.0, 1.0)       # an empty frame is a frame
    with pytest.raises(ValueError, match="set_wind: start"):
        c.features.set_wind((NAN, 0, 0))


def _missing_feature_calls(features):
    """Run the docs' frame loop calls on ``features`` (a Control's) and check each answer."""
    with pytest.raises(ValueError, match=r"set_collider_poses: the model has no colliders \(no Colliders feature "
                                         r"with shapes was given to Model.from_strands\), so it takes no poses; "
                                         r"got \(1, 7\)"):
        features.set_collider_poses([[0, 0, 0, 0, 0, 0, 1.0]], [[0, 0, 0, 0, 0, 0, 1.0]])
    features.set_collider_poses(np.zeros((0, 7)))             # no colliders, no poses: nothing to do
    with pytest.raises(ValueError, match=r"set_mesh_points: collider 0 is not a mesh: the model has no colliders"):
        features.set_mesh_points(0, _MESH)
    features.set_frame_time(0.0, 1 / 24)                     # only the wind reads it: nothing to do
    with pytest.raises(ValueError, match="set_frame_time: end 0.5 s is before start 1.0 s"):
        features.set_frame_time(1.0, 0.5)                    # but its times are still checked
    with pytest.raises(ValueError, match=r"set_wind: the model has no Wind feature"):
        features.set_wind((1.0, 0, 0))
    with pytest.raises(ValueError, match="the model has no RootBinding feature"):
        features.bound_roots(_SCALP)
    assert features.colliders is None and features.wind is None and features.pose is None
    features.resync()


@pytest.mark.parametrize("features", [None, [], [F.Drag(1.0)]], ids=["none", "empty", "drag only"])
def test_frame_calls_on_a_model_without_that_feature_name_it(features):
    """A model without features used to have control.features = None: the docs' frame loop
    (set_collider_poses, set_frame_time, ...) raised AttributeError on NoneType. Every model now
    answers the same, whatever features it has, and the solver still steps."""
    model = dw.Model.from_strands(_chain(), [6], device="cpu", features=features)
    control = model.control()
    assert control.features is not None
    _missing_feature_calls(control.features)
    with pytest.raises(ValueError, match="the model has no RootBinding feature"):
        control.bind_roots(_SCALP)
    solver = dw.make_solver(model, "dftl")
    state = solver.state()
    solver.advance(state, control, 1 / 24, 4)
    assert np.isfinite(model.points_from_device(state.positions)).all()


@pytest.mark.parametrize("device", ["cpu", "cpu,cpu"])
def test_frame_calls_on_a_simulation_without_features_name_them(tmp_path, device):
    from batch_stages import groom_stage

    from dftl_warp.simulation.settings import SimulationOptions
    from dftl_warp.simulation.simulate import Simulation

    sim = Simulation(dw.read_scene(str(groom_stage(tmp_path / "g.usda", strands=4, vertices=5, end=3))),
                     SimulationOptions(device=device), 1)
    _missing_feature_calls(sim.groups[0].control.features)
    sim.advance()


# -- 4. feature arguments ----------------------------------------------------------------------------


@pytest.mark.parametrize("make, fragment", [
    (lambda: F.Capsule(radius=0.1, half_height=0.1, axis="W"), r'axis must be "X", "Y" or "Z"'),
    (lambda: F.Capsule(radius=0.1, half_height=0.1, axis="y"), r'axis must be "X", "Y" or "Z"'),
    (lambda: F.Capsule(radius=0.1, half_height=0.1, axis=(0, 0, 0)), "axis must not be the zero vector"),
    (lambda: F.Capsule(radius=INF, half_height=0.1), "capsule radius"),
    (lambda: F.Sphere(radius=INF), "sphere radius must be > 0 and finite"),
    (lambda: F.Sphere(radius=1.0, rotation=(0, 0, 0, 0)), "rotation quaternion is zero"),
    (lambda: F.Wind(velocity=(1, 0, 0), noise_frequency=NAN), "noise_frequency"),
    (lambda: F.Wind(velocity=(1, 0, 0), noise_frequency=INF), "noise_frequency"),
    (lambda: F.HairHair(cell_size=INF), "cell_size"),
    (lambda: F.HairHair(0.01, extent=(-1, 1, 1)), "extent must be 3 finite lengths > 0"),
    (lambda: F.HairHair(0.01, max_cells=0), "max_cells"),
    (lambda: F.TriangleMesh(points=np.eye(3), indices=[0, 1, 2], sdf="yes"), "sdf must be True, False or None"),
    (lambda: F.TriangleMesh(points=np.zeros((3, 2)), indices=[0, 1, 2]), r"points must be .*\(P, 3\)"),
    (lambda: F.TriangleMesh(points=np.eye(3), indices=[0, 1]), r"indices must be \(T, 3\) or .*multiple of 3"),
    (lambda: F.RootBinding(np.eye(3), [0, 1, 2], triangles=[0], weights=[[2, -1, 0]]), "not barycentric"),
    (lambda: F.RootBinding(np.eye(3), [0, 1, 2], triangles=[0], weights=[[0.5, 0.2, 0.2]]), "not barycentric"),
    (lambda: F.RootBinding(np.eye(3), [0, 1, 2], triangles=[4], weights=[[1, 0, 0]]), r"triangles\[0\] = 4"),
    (lambda: F.RootBinding(np.array([[NAN, 0, 0], [1, 0, 0], [0, 1, 0]]), [0, 1, 2]),
     "root binding mesh points: row 0 is not finite"),
])
def test_feature_arguments_are_checked_at_construction(make, fragment):
    with pytest.raises(ValueError, match=fragment):
        make()


def test_capsule_axes_and_non_unit_rotation_accepted():
    for axis in ("X", "Y", "Z", (0.0, 2.0, 0.0)):
        F.Capsule(radius=0.1, half_height=0.1, axis=axis)
    # a non-unit quaternion names a rotation: normalised (documented on ColliderShape.rotation)
    assert np.allclose(F.Sphere(radius=1.0, rotation=(0, 0, 0, 2)).rotation, [0, 0, 0, 1])


def test_valid_root_binding_weights_accepted():
    F.RootBinding(np.eye(3), [0, 1, 2], triangles=[0], weights=[[0.2, 0.3, 0.5]])


@pytest.mark.parametrize("kw, fragment", [
    ({"widths": [1e-4, 2e-4]}, r"widths must be one value or one per point \(10\)"),
    ({"widths": np.full(10, NAN)}, r"widths\[0\]"),
    ({"widths": -1e-4}, r"widths\[0\]"),
])
def test_from_strands_checks_widths_without_features(kw, fragment):
    with pytest.raises(ValueError, match=fragment):
        dw.Model.from_strands(_chain(10), [10], device="cpu", **kw)


def test_from_strands_refuses_non_integer_counts():
    with pytest.raises(ValueError, match=r"counts\[0\] = 4.5 is not a whole number"):
        dw.Model.from_strands(_chain(5), [4.5, 0.5], device="cpu")
    assert dw.Model.from_strands(_chain(6), [3.0, 3.0], device="cpu").num_strands == 2


def test_root_targets_are_one_finite_row_per_strand():
    pts = np.stack([np.zeros(6), -np.arange(6) * 0.01, np.zeros(6)], 1)
    model = dw.Model.from_strands(np.concatenate([pts, pts + [0.1, 0, 0]]), [6, 6])
    control = model.control()
    roots = model.points[[0, 6]] if hasattr(model, "points") else np.array([[0.0, 0, 0], [0.1, 0, 0]])
    control.set_root_targets(roots)
    with pytest.raises(ValueError, match=r"root targets: row 1 is not finite"):
        control.set_root_targets(np.array([[0.0, 0, 0], [NAN, 0, 0]]))
    with pytest.raises(ValueError, match=r"must have shape \(2, 3\), one row per strand, got \(3, 3\)"):
        control.set_root_targets(roots, np.zeros((3, 3)))
    with pytest.raises(ValueError, match=r"got \(12, 3\)"):
        control.set_root_targets(np.zeros((12, 3)))          # a row per point, not per strand
    with pytest.raises(ValueError, match=r"got \(2, 2\)"):
        control.set_root_targets(np.zeros((2, 2)))


def test_make_solver_without_a_model_is_a_type_error():
    with pytest.raises(TypeError, match="make_solver: model must be a dftl_warp.Model .* got NoneType"):
        dw.make_solver(None, "elastic")


@pytest.mark.parametrize("device", ["gpu", "cuda:7"])
def test_a_device_warp_does_not_have_is_a_value_error_naming_the_device(device):
    """Warp's bare 'Invalid device identifier' named neither the argument nor what is there."""
    with pytest.raises(ValueError, match=rf"device '{device}' is not available here \(.*cpu.*\)"):
        dw.Model.from_strands(np.zeros((2, 3)), [2], device=device)


@pytest.mark.parametrize("device", ["gpu", "cuda:7"])
def test_simulate_strands_names_a_device_warp_does_not_have(device):
    """simulate_strands entered wp.ScopedDevice(device) first: Warp's bare 'Invalid device
    identifier: gpu' named neither the argument nor the devices there are."""
    with pytest.raises(ValueError, match=rf"^device '{device}' is not available here \(.*cpu.*\)"):
        dw.simulate_strands(np.c_[np.arange(3) * 0.01, np.zeros(3), np.zeros(3)], [3], steps=1, dt=0.01,
                            device=device)
