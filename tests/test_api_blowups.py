"""What the Python API says when a strand blows up: a researcher stepping solvers by hand reads
``solver.diagnostics(state)``; a NaN or infinite particle must show there, not read as a strand at
rest."""

import numpy as np
import pytest

import dftl_warp as dw
from conftest import chain


@pytest.mark.parametrize("field, index", [("positions", 3), ("velocities", 3), ("positions", 0),
                                          ("velocities", 0)])
def test_diagnostics_of_a_non_finite_strand_are_infinite_not_zero(field, index):
    """A strand with one NaN position or velocity reported max_stretch 0.0 and max_speed 0.0
    (``wp.max`` drops a NaN), so a blown-up run read as unstretched and still; now both are
    infinite, for that strand's NaN at its root or inside."""
    points = np.concatenate([chain(5, 0.02), chain(5, 0.02, origin=(0.5, 0, 0))])
    model = dw.Model.from_strands(points, [5, 5], precision="float64")
    solver = dw.make_solver(model, "dftl")
    state = solver.state()
    values = model.points_from_device(getattr(state, field), relative=field == "positions")
    values[5 + index] = np.nan
    state.write(field, model.points_to_device(values, relative=field == "positions"), layout=model.layout)
    d = solver.diagnostics(state)
    assert d["max_stretch"] == np.inf and d["max_speed"] == np.inf, d
    assert np.isnan(d["energy"]) or index == 0   # the root's energy is not counted
