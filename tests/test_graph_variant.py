"""On CUDA a frame's substeps are captured once in a CUDA graph and replayed (solvers/base.py:
launch_frame), and a graph replays the host scalars its launches were captured with. The elastic
step passes one that changes between frames: whether the clamp ghosts are offsets from the roots
(before any clamp targets are set, e.g. during the preroll) or targets of their own (set every frame
of an animated groom, on the device). Before, the graph key did not hold it: `simulate --preroll` on
a GPU captured the preroll's graph with relative ghosts and replayed it in the shot, where the
ghosts are absolute positions, so each clamp was placed at its root plus a world position
(tests/test_resume_preroll.py's uninterrupted and resumed runs differed on an H200). The CPU runs
without graphs, so this checks the key the CUDA path uses.
"""

import numpy as np

import dftl_warp as dw


def test_the_graph_key_holds_the_clamp_mode():
    pts = np.c_[np.zeros(6), -0.01 * np.arange(6), np.zeros(6)]
    model = dw.Model.from_strands(pts, [6], device="cpu", widths=80e-6)
    solver = dw.make_solver(model, "elastic")
    relative = solver.graph_variant()
    solver.clamp_target_arrays()                 # the device-side targets of an animated groom
    absolute = solver.graph_variant()
    solver.set_clamp_targets(None)               # back to ghosts carried with the roots
    assert relative != absolute and solver.graph_variant() == relative


def test_the_dftl_solver_keys_no_clamp_mode():
    pts = np.c_[np.zeros(6), -0.01 * np.arange(6), np.zeros(6)]
    model = dw.Model.from_strands(pts, [6], device="cpu")
    assert dw.make_solver(model, "dftl").graph_variant() == ()
