"""The elastic solver's host energy (``ElasticSolver.energy``) turns the root frame with the clamp, as
the step kernel does (its root frame is the minimal rotation onto the first segment after the
clamp's own turn). A rigid rotation of a strand at rest stores no elastic energy; before, the host
energy left out the clamp's turn, so a strand turned about its first segment, frames and clamp
with it, measured twist energy it does not have.
"""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import dftl_warp as dw
from dftl_warp.solvers.elastic_rest import mat_to_quat, quat_to_mat


def _curl():
    t = np.linspace(0.0, 3 * np.pi, 17)
    return np.c_[0.004 * np.cos(t) - 0.004, -0.006 * np.arange(17), 0.004 * np.sin(t)]


@pytest.mark.parametrize("angle", [0.4, 1.5])
def test_a_strand_turned_rigidly_with_its_clamp_stores_no_energy(angle):
    model = dw.Model.from_strands(_curl(), [17], device="cpu", precision="float64", widths=80e-6)
    solver = dw.make_solver(model, "elastic", gravity=(0.0, 0.0, 0.0))
    state = solver.state()
    assert solver.energy(state) == pytest.approx(0.0, abs=1e-15)   # at rest in its authored shape
    x = model.points_from_device(state.positions, relative=False)
    ghost = state.clamps.numpy()[0].astype(np.float64)
    axis = (x[0] - ghost) / np.linalg.norm(x[0] - ghost)             # the first segment's direction
    Q = Rotation.from_rotvec(angle * axis).as_matrix()
    state.write("positions", model.points_to_device(x[0] + (x - x[0]) @ Q.T, relative=False))
    state.clamps.assign((x[0] + Q @ (ghost - x[0]))[None])
    frames = state.frames.numpy().astype(np.float64)
    state.frames.assign(mat_to_quat(Q @ quat_to_mat(frames)))
    solver.set_clamp_targets(model.origin + (x[0] + Q @ (ghost - x[0]))[None], rotation_start=Q[None])
    # 80 um hair, 10 cm: EI / L is about 8e-8 J; a turn of 0.4 rad measured about 1e-7 J before
    assert solver.energy(state) == pytest.approx(0.0, abs=1e-15)
