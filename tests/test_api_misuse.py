"""The Python API as a notebook misuses it: States and Controls of another model, root_alpha
outside [0, 1], substeps=None, points of the wrong shape, a NaN origin, option values coerced by
``bool()``/``float()``, and simulate_strands' arrays. Each is one ValueError/TypeError naming the
argument, raised before a kernel reads another model's arrays past their ends."""

import numpy as np
import pytest

import dftl_warp as dw

NAN = float("nan")


def _strands(n=6, s=1):
    return np.concatenate([np.c_[np.full(n, 0.1 * k), -0.01 * np.arange(n), np.zeros(n)] for k in range(s)]), [n] * s


@pytest.fixture(scope="module")
def small():
    return dw.Model.from_strands(*_strands(), device="cpu")


@pytest.fixture(scope="module")
def big():
    return dw.Model.from_strands(*_strands(n=20, s=50), device="cpu")


# -- States and Controls of another model ---------------------------------------------------------


@pytest.mark.parametrize("name", ["dftl", "ftl", "pbd", "reference", "rattle"])
def test_a_state_of_another_model_is_refused_not_read_past_its_end(small, big, name):
    """A 6-particle State stepped by a 1000-particle model's solver: its kernels read and wrote
    994 slots past the arrays' end (garbage, NaN, or a crash); now a ValueError naming it."""
    solver = dw.make_solver(big, name)
    state = dw.make_solver(small, name).state()
    with pytest.raises(ValueError, match=r"state\.positions is not this model's \(6 slots .* has 1000 "):
        solver.advance(state, big.control(), 1 / 240, 2)
    with pytest.raises(ValueError, match=r"state_in\.positions is not this model's"):
        solver.step(state, state, big.control(), 1 / 240)
    own = solver.state()
    with pytest.raises(ValueError, match=r"state_out\.positions is not this model's"):
        solver.step(own, state, big.control(), 1 / 240)
    with pytest.raises(ValueError, match=r"state\.positions is not this model's"):
        solver.diagnostics(state)


def test_a_control_of_another_model_is_refused(small, big):
    solver = dw.make_solver(big, "dftl")
    state = solver.state()
    before = big.points_from_device(state.positions)
    with pytest.raises(ValueError, match=r"control was made by another model"):
        solver.advance(state, small.control(), 1 / 240, 2)
    np.testing.assert_array_equal(big.points_from_device(state.positions), before)   # nothing ran


def test_a_state_of_another_precision_is_a_value_error_not_a_warp_launch_error(small):
    model64 = dw.Model.from_strands(*_strands(), device="cpu", precision="float64")
    with pytest.raises(ValueError, match=r"state\.positions is not this model's \(6 slots of vec3d .* of vec3f"):
        dw.make_solver(small, "dftl").advance(dw.make_solver(model64, "dftl").state(), small.control(), 0.01, 1)


def test_none_for_a_state_or_control_is_a_type_error_naming_it(small):
    solver = dw.make_solver(small, "dftl")
    with pytest.raises(TypeError, match=r"state must be a dftl_warp\.State .* got NoneType"):
        solver.advance(None, small.control(), 0.01, 1)
    with pytest.raises(TypeError, match=r"control must be a dftl_warp\.Control .* got NoneType"):
        solver.advance(solver.state(), None, 0.01, 1)


@pytest.mark.parametrize("alpha", [NAN, -0.5, 2.0, float("inf"), "1", True])
def test_root_alpha_outside_the_frame_is_refused(small, alpha):
    """step(..., root_alpha=nan) put every particle at NaN without a word."""
    solver = dw.make_solver(small, "dftl")
    state = solver.state()
    with pytest.raises(ValueError, match=r"root_alpha must be a number in \[0, 1\]"):
        solver.step(state, state, small.control(), 1 / 240, alpha)
    assert np.isfinite(small.points_from_device(state.positions)).all()


def test_substeps_none_names_substeps(small):
    """advance(..., substeps=None) was a TypeError from range() deep in the solver."""
    solver = dw.make_solver(small, "dftl")
    with pytest.raises(ValueError, match=r"substeps must be an integer >= 1, got None"):
        solver.advance(solver.state(), small.control(), 0.01, None)


def test_rest_of_the_api_still_steps():
    model = dw.Model.from_strands(np.c_[0.01 * np.arange(6), np.zeros(6), np.zeros(6)], [6])   # horizontal: falls
    solver = dw.make_solver(model, "dftl")
    a, b = solver.state(), solver.state()
    control = model.control()
    solver.step(a, b, control, 1 / 240, 0.5)
    solver.advance(b, control, 1 / 240, 3)
    assert np.isfinite(model.points_from_device(b.positions)).all()
    assert solver.diagnostics(b)["max_speed"] > 0


# -- Model.from_strands: shapes and origin ----------------------------------------------------------


@pytest.mark.parametrize("shape", [(6, 2), (3, 4), (2, 9)])
def test_points_of_another_width_are_refused_not_reshaped(shape):
    """(6, 2) x, y pairs (12 numbers) were reshaped to 4 points of 3 without a word."""
    points = np.arange(np.prod(shape), dtype=float).reshape(shape)
    with pytest.raises(ValueError, match=rf"points must have shape \(N, 3\), got \({shape[0]}, {shape[1]}\)"):
        dw.Model.from_strands(points, [4])
    with pytest.raises(ValueError, match=r"points must have shape \(N, 3\)"):
        dw.RenderScene.from_strands(points, [4])


def test_points_of_odd_dtypes_and_layouts_give_the_same_model():
    points, counts = _strands(s=2)
    reference = dw.Model.from_strands(points, counts)
    for variant in (points.astype(np.float32), np.asfortranarray(points), np.repeat(points, 2, axis=1)[:, ::2],
                    points.reshape(2, 6, 3), points.reshape(-1), [tuple(p) for p in points]):
        m = dw.Model.from_strands(variant, np.array(counts, dtype=np.int32))
        np.testing.assert_allclose(m.points_from_device(m.rest_positions), reference.points_from_device(
            reference.rest_positions), atol=1e-7)


@pytest.mark.parametrize("origin", [[0.0, 0.0, NAN], [0.0, 0.0], "abc"])
def test_origin_must_be_three_finite_numbers(origin):
    """origin=(0, 0, nan) made every device position NaN; (0, 0) was numpy's reshape error."""
    with pytest.raises(ValueError, match=r"origin must be 3 finite numbers \(m\)"):
        dw.Model.from_strands(*_strands(), origin=origin)


def test_a_fractional_interleave_is_refused_not_truncated():
    with pytest.raises(ValueError, match=r"interleave must be a whole number of state vectors, got 2.5"):
        dw.Model.from_strands(*_strands(), layout="particle-major", interleave=2.5)


# -- solver options coerced by bool() / float() ------------------------------------------------------


@pytest.mark.parametrize("name, kw, fragment", [
    ("dftl", {"fused": "no"}, r"fused must be True or False, got 'no'"),
    ("ftl", {"fused": 0}, r"fused must be True or False, got 0"),
    ("dftl", {"damping": "0.5"}, r"damping must be in \[0, 1\], got '0.5'"),
    ("dftl", {"damping": True}, r"damping must be in \[0, 1\], got True"),
])
def test_solver_options_are_not_coerced(small, name, kw, fragment):
    """fused="no" was bool("no"): fused substeps on; damping="0.5" was float("0.5")."""
    with pytest.raises(ValueError, match=fragment):
        dw.make_solver(small, name, **kw)


def test_valid_dftl_options_still_build(small):
    assert dw.make_solver(small, "dftl", damping=np.float32(0.5), fused=False).damping == 0.5
    assert dw.make_solver(small, "dftl", damping=1, fused=np.bool_(False)).fused is False


# -- simulate_strands --------------------------------------------------------------------------------


def _one():
    return np.c_[0.01 * np.arange(5), np.zeros(5), np.zeros(5)], [5]


def test_simulate_strands_refuses_fractional_counts():
    """counts [5.5] went through astype(int64) (5) before Model.from_strands could see it."""
    points, _ = _one()
    with pytest.raises(ValueError, match=r"counts\[0\] = 5.5 is not a whole number"):
        dw.simulate_strands(points, [5.5], steps=1, dt=0.01)


@pytest.mark.parametrize("kw, fragment", [
    ({"velocities": np.full((5, 3), NAN)}, r"velocities\[0\] is not finite"),
    ({"velocities": np.zeros((4, 3))}, r"velocities must have shape \(5, 3\).*got \(4, 3\)"),
    ({"velocities": np.zeros((5, 2))}, r"velocities must have shape \(5, 3\).*got \(5, 2\)"),
    ({"roots": np.zeros((2, 1, 3))}, r"roots must have shape \(3, 1, 3\): \(steps \+ 1, S, 3\).*got \(2, 1, 3\)"),
    ({"roots": np.r_[np.zeros((2, 1, 3)), np.full((1, 1, 3), NAN)]}, r"roots\[2, 0\] is not finite"),
])
def test_simulate_strands_names_bad_velocities_and_roots(kw, fragment):
    """NaN velocities were stepped without a word; wrong shapes were numpy's broadcast errors."""
    points, counts = _one()
    with pytest.raises(ValueError, match=fragment):
        dw.simulate_strands(points, counts, steps=2, dt=0.01, **kw)


def test_simulate_strands_with_velocities_and_roots_still_runs():
    points, counts = _one()
    roots = np.zeros((3, 1, 3))
    roots[:, 0, 1] = [0.0, 0.001, 0.002]
    rec = dw.simulate_strands(points, np.array([5.0]), steps=2, dt=0.01, velocities=np.ones((5, 3)), roots=roots)
    assert rec.positions.shape == (3, 5, 3)
    np.testing.assert_allclose(rec.positions[-1, 0], [0.0, 0.002, 0.0], atol=1e-6)
