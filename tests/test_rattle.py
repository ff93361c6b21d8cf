"""The production second-order solver (``rattle``): order, energy, exact lengths, no NaN."""

import numpy as np
import pytest

from dftl_warp.core.model import Model
from dftl_warp.solvers import make_solver
from dftl_warp.study import scenarios as sc
from dftl_warp.study.sweeps import chain_energy, fitted_slope, max_stretch, trajectory_error

G = (0.0, -sc.GRAVITY, 0.0)
PRECISIONS = ["float32", "float64"]


def _run(points, counts, solver, precision, frames, frame_dt, substeps, **kw):
    model = Model.from_strands(points, counts, device="cpu", precision=precision)
    s = make_solver(model, solver, gravity=G, **kw.pop("options", {}))
    x, v = sc.record(s, frames, frame_dt, substeps, **kw)
    return s, x, v


def swinging_strand(particles=8, length=0.2, angle=np.pi / 4):
    """A straight strand hanging from the origin, released ``angle`` from straight down."""
    t = np.linspace(0.0, length, particles)
    return np.stack([t * np.sin(angle), -t * np.cos(angle), 0.0 * t], axis=1)


def test_registered_and_in_the_options():
    from dftl_warp.options import OPTIONS
    from dftl_warp.solvers import SOLVERS

    assert "rattle" in SOLVERS and "rattle" in OPTIONS["solver"].choices


def test_second_order_against_the_converged_reference():
    """Falling chain (10 particles, 1 m, 0.25 s): error ~ dt^2 against the reference at a fine step."""
    pts, counts = sc.horizontal_chain(10, 1.0), [10]
    _, ref, _ = _run(pts, counts, "reference", "float64", 10, 0.025, 640)
    substeps = [5, 10, 20, 40]
    errors = [trajectory_error(_run(pts, counts, "rattle", "float64", 10, 0.025, k)[1], ref, 1.0) for k in substeps]
    slope = fitted_slope([0.025 / k for k in substeps], errors)
    assert 1.8 < slope < 2.2, (slope, errors)
    # float32 at production steps: the same truncation error (round-off is far below it)
    e32 = trajectory_error(_run(pts, counts, "rattle", "float32", 10, 0.025, 10)[1], ref, 1.0)
    assert e32 == pytest.approx(errors[1], rel=0.2)


@pytest.mark.parametrize("precision", PRECISIONS)
def test_free_swing_conserves_energy(precision):
    """A strand released at 45 degrees swings freely for 1.5 s at 16 substeps per 1/24 s frame.

    RATTLE is symplectic: the energy oscillates with an amplitude O(dt^2) and does not drift.
    Scale: n g L (the potential energy range of the strand). DFTL loses most of it in 1 s."""
    pts = swinging_strand()
    s, x, v = _run(pts, [len(pts)], "rattle", precision, 36, 1 / 24, 16)
    e = chain_energy(x, v)
    scale = (len(pts) - 1) * sc.GRAVITY * 0.2
    rel = (e - e[0]) / scale
    assert np.abs(rel).max() < 2e-3, np.abs(rel).max()
    assert abs(rel[-12:].mean() - rel[:12].mean()) < 1e-3  # no drift between the first and last half second
    assert s.diagnostics(s.state())["fallbacks"] == 0
    # the same swing under DFTL loses a large share of its energy: the contrast the solver is for
    _, xd, vd = _run(pts, [len(pts)], "dftl", precision, 36, 1 / 24, 16)
    assert (chain_energy(xd, vd)[-1] - e[0]) / scale < -0.05


@pytest.mark.parametrize("precision", PRECISIONS)
def test_inextensible_to_round_off(precision):
    pts, counts = sc.groom(16, 12, 0.2)
    roots0 = pts[sc.strand_starts(counts)]
    s, x, _ = _run(pts, counts, "rattle", precision, 12, 1 / 24, 8, roots=lambda t: sc.head_roots(roots0, t))
    rest = np.linalg.norm(np.diff(pts, axis=0), axis=1)
    stretch = max_stretch(x, counts, rest).max()
    assert stretch < (2e-6 if precision == "float32" else 1e-12), stretch
    assert np.isfinite(x).all()


@pytest.mark.parametrize("precision", PRECISIONS)
def test_teleporting_root_never_nan(precision):
    """The root jumps a metre every frame (twenty strand lengths): finite, lengths kept."""
    pts = swinging_strand(10, 0.05)
    s, x, v = _run(pts, [10], "rattle", precision, 6, 1 / 24, 4,
                   roots=lambda t: np.array([[np.floor(24 * t + 1e-9) * 1.0, 0.0, 0.0]]))
    assert np.isfinite(x).all() and np.isfinite(v).all()
    rest = np.linalg.norm(np.diff(pts, axis=0), axis=1)
    # round-off: float32 positions ~6 m from the origin are stored to ~5e-7 m, ~1e-4 of a 5.6 mm segment
    ulp = (2.0**-23 if precision == "float32" else 2.0**-52) * np.abs(x).max()
    assert max_stretch(x, [10], rest).max() < 4 * ulp / rest.min()
    assert np.allclose(x[1:, 0, 0], np.arange(1, 7), atol=1e-5)


def test_step_matches_advance_of_one_substep():
    pts = swinging_strand()
    model = Model.from_strands(pts, [len(pts)], device="cpu", precision="float64")
    a = make_solver(model, "rattle", gravity=G)
    b = make_solver(model, "rattle", gravity=G)
    sa, sb, control = a.state(), b.state(), model.control()
    a.advance(sa, control, 1e-3, 1)
    b.step(sb, sb, control, 1e-3)
    assert np.array_equal(sa.positions.numpy(), sb.positions.numpy())


def test_options_are_checked():
    model = Model.from_strands(swinging_strand(), [8], device="cpu")
    with pytest.raises(ValueError):
        make_solver(model, "rattle", newton_iterations=0)
    with pytest.raises(ValueError):
        make_solver(model, "rattle", max_halvings=-1)


def mixed_groom(counts, seed=0, segment=0.01):
    """Strands of the given vertex counts, random directions, roots scattered about the origin."""
    rng = np.random.default_rng(seed)
    pts = []
    for c in counts:
        d = rng.normal(size=(c, 3))
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        chain = np.vstack([np.zeros(3), np.cumsum(d[:-1] * segment, axis=0)])
        pts.append(rng.normal(size=3) * 0.05 + chain)
    return np.vstack(pts)


#: lengths on every side of the on-chip capacities (8/16/24/32), a lone root and a two-particle
#: strand, and one longer than 32 (the global-memory kernel) between them
MIXED_COUNTS = [5, 8, 32, 12, 40, 1, 2, 17, 24, 32, 9, 3]


@pytest.mark.parametrize("precision", PRECISIONS)
@pytest.mark.parametrize("substeps", [1, 2, 8])
def test_on_chip_equals_global_memory_kernel(precision, substeps):
    """The on-chip kernel (strands <= 32 vertices in thread-local storage) repeats the global-memory
    kernel's arithmetic: bitwise the same positions, velocities and statistics on the CPU, on a
    mixed groom with moving roots (the head turns), substeps halved where the whip demands."""
    counts = MIXED_COUNTS if precision == "float32" else [5, 12, 40, 1, 2, 9, 3]  # fewer compiles
    pts = mixed_groom(counts)
    roots0 = pts[sc.strand_starts(counts)]
    out = []
    for on_chip in (False, True):
        s, x, v = _run(pts, counts, "rattle", precision, 4, 1 / 24, substeps, options={"on_chip": on_chip},
                       roots=lambda t: sc.head_roots(roots0, 3.0 * t))
        assert s.on_chip is on_chip
        out.append((x, v, s.diagnostics(s.state())))
    (xg, vg, dg), (xc, vc, dc) = out
    assert np.isfinite(xc).all() and np.isfinite(vc).all()
    assert np.array_equal(xg, xc), np.abs(xg - xc).max()
    assert np.array_equal(vg, vc), np.abs(vg - vc).max()
    assert dg["constraint_residual"] == dc["constraint_residual"] and dg["fallbacks"] == dc["fallbacks"]


def test_on_chip_runs():
    """Consecutive strands share a run per capacity; longer strands (and on_chip off) take the
    global-memory kernel (None); the on-chip kernel runs only when asked for (the H200 measured it slower)."""
    import warp as wp

    from dftl_warp.solvers.rattle import rattle_runs

    runs = rattle_runs([5, 8, 9, 40, 33, 32, 1], wp.float64, True)
    assert [(r[0] is None, r[1], r[2]) for r in runs] == [(False, 0, 2), (False, 2, 1), (True, 3, 2), (False, 5, 1),
                                                           (False, 6, 1)]
    assert rattle_runs([5, 40], wp.float64, False)[0][0] is None and len(rattle_runs([5, 40], wp.float64, False)) == 1
    model = Model.from_strands(swinging_strand(), [8], device="cpu")
    assert make_solver(model, "rattle").on_chip is False
