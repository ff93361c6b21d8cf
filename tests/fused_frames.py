"""Grooms and frames for the fused-substep tests: random strands, roots swinging inside every frame."""

import numpy as np

import dftl_warp as dw


def random_groom(rng, lengths):
    """Random strands of the given vertex counts (segments of 0.02), roots spread over [-5, 5]^3."""
    pts = []
    for n in lengths:
        steps = rng.normal(size=(n, 3))
        steps /= np.linalg.norm(steps, axis=1, keepdims=True)
        steps[0] = rng.uniform(-5, 5, size=3)
        pts.append(np.cumsum(steps * 0.02, axis=0))
    return np.concatenate(pts), np.array(lengths)


def swing_roots(control, roots, frame):
    """Root targets of ``frame``: the roots swing on a circle, so they move inside every launch."""
    offset = lambda a: 0.05 * np.array([np.sin(a), 1 - np.cos(a), 0.3 * a])  # noqa: E731
    control.set_root_targets(roots + offset(0.7 * frame), roots + offset(0.7 * (frame + 1)))


def simulate(pts, counts, *, fused, precision, layout, substeps, frames, correction="prior"):
    """``frames`` frames of ``substeps`` substeps: positions, velocities and corrections (None in
    the posterior form) in input order, and the solver."""
    # "interleaved": particle-major with positions, velocities and corrections interleaved per
    # 32-strand chunk (the CUDA default, built here on the CPU)
    name, interleave = ("particle-major", 3) if layout == "interleaved" else (layout, None)
    model = dw.Model.from_strands(pts, counts, precision=precision, layout=name, interleave=interleave)
    solver = dw.DFTLSolver(model, correction=correction, fused=fused, gravity=(0.0, -9.81, 0.0))
    state, control = solver.state(), model.control()
    roots = pts[np.concatenate([[0], np.cumsum(counts)[:-1]])]
    for frame in range(frames):
        swing_roots(control, roots, frame)
        solver.advance(state, control, 1 / 240, substeps)
    corrections = None if state.corrections is None else state.corrections.numpy()[model.layout.slot_of_point]
    return (model.points_from_device(state.positions), model.points_from_device(state.velocities, relative=False),
            corrections, solver)
