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
