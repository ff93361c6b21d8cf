"""The Model is immutable, its host arrays included: ``model.origin[0] = nan``, ``model.counts[:] =
...`` and edits of the rest positions or the layout were taken without a word (NaN output, a model
whose counts no longer match its device arrays). ``dataclasses.replace`` cannot change the
precision or the device (Warp's launch failed with "expects dtype=vec_t but passed dtype=vec_t")."""

import dataclasses

import numpy as np
import pytest

import dftl_warp as dw
from dftl_warp.core.synthetic import uniform_groom

MODEL_ARRAYS = ("counts", "origin", "rest_positions", "widths")
LAYOUT_ARRAYS = ("strand_order", "strand_base", "strand_stride", "strand_count", "slot_of_point")


def _strands():
    chain = np.c_[np.arange(5) * 0.01, np.zeros(5), np.zeros(5)]
    return np.concatenate([chain, chain + [0.5, 0, 0]]), [5, 5]


@pytest.mark.parametrize("layout", ["strand-major", "particle-major"])
def test_host_arrays_of_a_model_and_its_layout_are_read_only(layout):
    model = dw.Model.from_strands(*_strands(), device="cpu", layout=layout, widths=np.full(10, 1e-4))
    arrays = [(f"model.{n}", getattr(model, n)) for n in MODEL_ARRAYS]
    arrays += [(f"model.layout.{n}", getattr(model.layout, n)) for n in LAYOUT_ARRAYS]
    for label, array in arrays:
        assert isinstance(array, np.ndarray) and not array.flags.writeable, label
        with pytest.raises(ValueError, match="read-only"):
            array[0] = array[0]


def test_edits_in_place_are_refused_and_the_model_steps_as_built():
    model = dw.Model.from_strands(*_strands(), device="cpu")
    with pytest.raises(ValueError, match="read-only"):
        model.origin[0] = np.nan
    with pytest.raises(ValueError, match="read-only"):
        model.counts[:] = [3, 7]
    with pytest.raises(ValueError, match="read-only"):
        model.rest_positions[0] = 1.0
    solver = dw.make_solver(model, "dftl")
    state = solver.state()
    solver.advance(state, model.control(), 0.01, 2)
    assert np.isfinite(model.points_from_device(state.positions)).all()


def test_the_callers_origin_and_widths_are_copied():
    """The model took the caller's float64 origin and widths arrays as they were: a later edit of
    the caller's array changed the model."""
    origin, widths = np.array([0.1, 0.0, 0.0]), np.full(10, 1e-4)
    model = dw.Model.from_strands(*_strands(), device="cpu", origin=origin, widths=widths)
    origin[0], widths[0] = np.nan, -1.0
    assert model.origin.tolist() == [0.1, 0.0, 0.0]
    assert model.widths[0] == 1e-4


def test_a_synthetic_grooms_host_arrays_are_read_only_views():
    model, _ = uniform_groom(4, 3, device="cpu")
    assert not model.counts.flags.writeable and not model.layout.strand_base.flags.writeable
    # views, not copies: the model's counts are its layout's
    assert np.shares_memory(model.counts, model.layout.strand_count)


@pytest.mark.parametrize("changes, fragment", [
    (dict(precision="float64"), r"precision 'float64' on cpu does not match its arrays \(float32 on cpu\)"),
    (dict(precision="float16"), r"unknown precision 'float16'"),
])
def test_replace_cannot_change_the_precision(changes, fragment):
    model = dw.Model.from_strands(*_strands(), device="cpu")
    with pytest.raises(ValueError, match=fragment) as caught:
        dataclasses.replace(model, **changes)
    assert "\n" not in str(caught.value)


def test_replace_that_keeps_the_arrays_steps_as_the_original():
    model = dw.Model.from_strands(*_strands(), device="cpu", precision="float64")
    twin = dataclasses.replace(model, precision="float64")
    assert not twin.origin.flags.writeable
    out = []
    for m in (model, twin):
        solver = dw.make_solver(m, "dftl")
        state = solver.state()
        solver.advance(state, m.control(), 0.01, 3)
        out.append(m.points_from_device(state.positions))
    np.testing.assert_array_equal(out[0], out[1])
