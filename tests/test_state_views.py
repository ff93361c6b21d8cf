"""Whole-array writes to a State's fields on an interleaved layout (CUDA's default).

There the positions, velocities and corrections are views of one buffer, 32 slots apart, and a
view's entries past its chunk's first 32 are the other fields' slots. ``state.velocities.assign(
model.points_to_device(v))``, the way Newton's users set a State, wrote zeros over the positions of
every particle past the first row: a standing column set moving at 0.1 mm/s fell from its root on
the H200, where the CPU (strand-major, no views) held it. A view's ``assign``, ``zero_`` and
``fill_`` now write its own field's slots only."""

import numpy as np
import pytest

import dftl_warp as dw


def _hanging(strands=40, count=5):
    """``strands`` hanging chains of ``count`` points, 1 cm apart: more than one 32-strand chunk."""
    x = np.repeat(np.arange(strands) * 0.02, count)
    y = -np.tile(np.arange(count) * 0.01, strands)
    return np.stack([x, y, np.zeros_like(x)], 1), [count] * strands


@pytest.mark.parametrize("interleave", [2, 3])
def test_assign_zero_and_fill_on_a_view_keep_the_other_fields(interleave):
    pts, counts = _hanging()
    model = dw.Model.from_strands(pts, counts, layout="particle-major", interleave=interleave)
    state = model.state(with_corrections=interleave == 3)
    assert state.storage is not None
    v = np.random.default_rng(1).normal(size=pts.shape)
    state.velocities.assign(model.points_to_device(v, relative=False))
    assert np.allclose(model.points_from_device(state.positions), pts, atol=1e-7)
    assert np.allclose(model.points_from_device(state.velocities, relative=False), v, atol=1e-6)
    state.velocities.fill_((0.0, 0.0, 2.0))
    assert np.array_equal(model.points_from_device(state.velocities, relative=False),
                          np.tile([0.0, 0.0, 2.0], (len(pts), 1)))
    state.velocities.zero_()
    assert not model.points_from_device(state.velocities, relative=False).any()
    assert np.allclose(model.points_from_device(state.positions), pts, atol=1e-7)
    if interleave == 3:
        state.corrections.fill_((1.0, 1.0, 1.0))
        assert np.allclose(model.points_from_device(state.positions), pts, atol=1e-7)
        assert not model.points_from_device(state.velocities, relative=False).any()


def test_velocities_set_through_a_view_move_the_hair_as_on_a_plain_layout():
    """The same kick, set through ``state.velocities.assign``, on the strand-major layout (no
    views) and an interleaved particle-major one: the same motion, to float32 round-off."""
    pts, counts = _hanging()
    kick = np.zeros_like(pts)
    kick[:, 0] = 0.5
    out = []
    for layout, interleave in (("strand-major", 1), ("particle-major", 3)):
        model = dw.Model.from_strands(pts, counts, layout=layout, interleave=interleave)
        solver = dw.DFTLSolver(model)
        state, control = solver.state(), model.control()
        state.velocities.assign(model.points_to_device(kick, relative=False))
        for _ in range(6):
            solver.advance(state, control, 1.0 / 240.0, 10)
        out.append(model.points_from_device(state.positions, relative=False))
    assert np.abs(out[0] - pts).max() > 0.01          # it moved
    assert np.allclose(out[0], out[1], atol=1e-5), np.abs(out[0] - out[1]).max()


def test_write_needs_no_layout_and_ignores_one_given():
    """``State.write`` finds a field's slots from its storage: the ``layout`` argument callers still
    passed is ignored (accepted for older scripts), and the package's own calls leave it out."""
    import ast
    from pathlib import Path

    pts, counts = _hanging()
    model = dw.Model.from_strands(pts, counts, layout="particle-major", interleave=3)
    other = dw.Model.from_strands(pts[:10], [5, 5], layout="strand-major")
    v = np.random.default_rng(2).normal(size=pts.shape)
    for layout in ({}, {"layout": other.layout}):
        state = model.state()
        state.write("velocities", model.points_to_device(v, relative=False), **layout)
        assert np.allclose(model.points_from_device(state.velocities, relative=False), v, atol=1e-6)
        assert np.allclose(model.points_from_device(state.positions), pts, atol=1e-7)
    package = Path(dw.__file__).parent
    passing = []
    for path in sorted(package.rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text())):
            if (isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute) and node.func.attr == "write"
                    and any(k.arg == "layout" for k in node.keywords)):
                passing.append(f"{path.relative_to(package)}:{node.lineno}")
    assert not passing, f"State.write(..., layout=) needs no layout: {passing}"
