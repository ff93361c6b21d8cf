"""Rest shapes that are unstable equilibria: hair standing beyond its buckling length, or held out
horizontally beyond the length its twist can hold.

A vertical column of hair clamped at its root buckles under its own weight at
``L = (7.837 EI / (rho A g))^(1/3) = 1.9863 l_b`` (Greenhill 1881). Inverse statics makes a taller
standing strand an equilibrium, but an unstable one: the solver lets it fall at the first
disturbance. The stability test (``dftl_warp/solvers/elastic_stability.py``) finds Greenhill's
length, the solver holds a column below it and drops one above it, and ``simulate`` says so.

A horizontal strand is held straight by a rest curvature against its weight; twisted about its
axis, that curvature turns away from holding it, and beyond a length (2.97 l_b for 80 um hair) the
twist stiffness cannot hold it: it twists over. No segment is compressed; only the frames (the
twist couplings) show it. The test flags it with the frames, the solver drops it.
"""

import numpy as np
from scipy.optimize import brentq

import dftl_warp as dw
from dftl_warp.solvers import elastic_rest
from dftl_warp.solvers.elastic import HAIR_DENSITY, HAIR_E, TWIST_G
from dftl_warp.solvers.elastic_stability import holding_scales, stiffness_margins, unstable_strands

R, G0, N = 40e-6, 9.81, 32
EI = HAIR_E * np.pi * R ** 4 / 4
LB = (EI / (HAIR_DENSITY * np.pi * R ** 2 * G0)) ** (1.0 / 3.0)
GREENHILL = 7.837 ** (1.0 / 3.0)          # critical length of a clamped column under its own weight, in l_b


def column(length, n=N):
    s = np.linspace(0.0, length, n + 1)
    return np.stack([np.zeros_like(s), s, np.zeros_like(s)], -1)


def margin(ratio, n=N):
    grp = elastic_rest.RodGroup(column(ratio * LB, n)[None], np.full((1, n + 1), R), E=HAIR_E, G=TWIST_G,
                                rho=HAIR_DENSITY, gravity=(0.0, -G0, 0.0), inverse_statics=True)
    return stiffness_margins(grp)[0]


def rod_group(points):
    return elastic_rest.RodGroup(points[None], np.full((1, len(points)), R), E=HAIR_E, G=TWIST_G,
                                 rho=HAIR_DENSITY, gravity=(0.0, -G0, 0.0), inverse_statics=True)


def test_the_stability_test_finds_greenhills_buckling_length():
    critical = brentq(margin, 1.5, 2.5)
    assert abs(critical / GREENHILL - 1) < 5e-3, critical
    # the stiffness that holds a taller column: EI grows as L^3 at the critical length
    for ratio in (1.5, 2.5, 4.0):
        scale = holding_scales(rod_group(column(ratio * LB)))[0]
        assert abs(scale / (ratio / GREENHILL) ** 3 - 1) < 5e-3, (ratio, scale)
    hanging = elastic_rest.RodGroup((column(3 * LB) * [1, -1, 1])[None], np.full((1, N + 1), R), E=HAIR_E,
                                    G=TWIST_G, rho=HAIR_DENSITY, gravity=(0.0, -G0, 0.0), inverse_statics=True)
    assert stiffness_margins(hanging)[0] > 0


def test_the_solver_holds_a_column_below_it_and_drops_one_above_it():
    """Columns of 1.8 and 2.2 l_b, pushed sideways at 0.1 mm/s at the tip: after 2 s the first
    stands within 1e-3 of its length, the second has fallen; only the second is flagged."""
    moved = {}
    for ratio in (1.8, 2.2):
        pts = column(ratio * LB)
        model = dw.Model.from_strands(pts, [N + 1], precision="float64")
        solver = dw.make_solver(model, "elastic", radius=R)
        state, control = solver.state(), model.control()
        push = np.zeros((N + 1, 3))
        push[:, 0] = 1e-4 * pts[:, 1] / pts[-1, 1]
        state.write("velocities", model.points_to_device(push, relative=False))
        flagged, _, tested, total = solver.unstable_strands()
        assert tested == total == 1 and flagged.tolist() == ([0] if ratio > GREENHILL else [])
        for _ in range(48):
            solver.advance(state, control, 1.0 / (24 * 8), 8)
        moved[ratio] = np.linalg.norm(model.points_from_device(state.positions)[-1] - pts[-1]) / (ratio * LB)
    assert moved[1.8] < 1e-3 and moved[2.2] > 0.3, moved


def test_simulate_says_which_strands_can_fall(tmp_path, capsys):
    from usd_stages import add_curves, new_stage

    from dftl_warp import cli

    stage = new_stage(tmp_path / "in.usda", start=1, end=2)
    tall = column(2.5 * LB)
    add_curves(stage, "/World/Mohawk", np.concatenate([tall, tall + [0.01, 0, 0], tall * [1, -1, 1] + [0.02, 0, 0]]),
               [N + 1] * 3, widths=2 * R, bending=None)
    stage.Save()
    assert cli.main(["simulate", str(tmp_path / "in.usda"), "-o", str(tmp_path / "out.usdc")]) == 0
    err = capsys.readouterr().err
    # both columns are 2.5 l_b: (2.5 / 1.9863)^3 = 1.994 holds them
    assert ("/World/Mohawk: 2 of the 3 strands rest in an unstable equilibrium" in err
            and "primvars:dftl:bendStiffnessScale of 1.99 holds half of them, 1.99 all" in err), err
    # one unstable strand: the scale that holds it (it said 'holds half of them, ... all')
    stage = new_stage(tmp_path / "one.usda", start=1, end=2)
    add_curves(stage, "/World/Mohawk", np.concatenate([tall, tall * [1, -1, 1] + [0.02, 0, 0]]), [N + 1] * 2,
               widths=2 * R, bending=None)
    stage.Save()
    assert cli.main(["simulate", str(tmp_path / "one.usda"), "-o", str(tmp_path / "one.usdc")]) == 0
    err = capsys.readouterr().err
    assert ("1 of the 2 strands rests in an unstable equilibrium" in err
            and "primvars:dftl:bendStiffnessScale of 1.99 holds it" in err and "half" not in err), err


def test_the_frames_blocks_are_the_energys_second_derivatives():
    """The frames' blocks of the stiffness (elastic_stability.frame_blocks) against central finite
    differences of RodGroup.energy, in the positions and a rotation exp([w_j]) of each frame, on a
    curved strand whose inverse statics carries bending moments and twist."""
    from dftl_warp.solvers.elastic_rest import expm_so3
    from dftl_warp.solvers.elastic_stability import frame_blocks

    n = 6
    t = np.linspace(0.0, 1.5, n + 1)
    rest = np.stack([0.02 * np.sin(3 * t), 0.01 * t + 0.02 * np.cos(2 * t), 0.015 * t], -1)
    grp = rod_group(rest)
    assert np.abs(grp.b).max() > 0 and np.abs(grp.Qb - np.eye(3)).max() > 1e-6
    cross, frames = frame_blocks(grp, np.arange(1))
    m = 3 * n

    def energy(z):
        x = rest.copy()
        x[1:] = z[:m].reshape(n, 3)
        return grp.energy(x[None], np.zeros((1, n + 1, 3)), expm_so3(z[m:].reshape(1, n, 3)), grp.ghost,
                          np.zeros(3))[0]

    z0 = np.concatenate([rest[1:].ravel(), np.zeros(m)])
    h = 1e-4
    H = np.zeros((2 * m, 2 * m))
    for i in range(2 * m):
        for k in range(i, 2 * m):
            e = [energy(z0 + a * h * np.eye(2 * m)[i] + b * h * np.eye(2 * m)[k]) for a, b in ((1, 1), (1, -1), (-1, 1), (-1, -1))]
            H[i, k] = H[k, i] = (e[0] - e[1] - e[2] + e[3]) / (4 * h * h)
    assert np.abs(cross[0] - H[:m, m:]).max() < 1e-6 * np.abs(H[:m, m:]).max()
    assert np.abs(frames[0] - H[m:, m:]).max() < 1e-6 * np.abs(H[m:, m:]).max()


def test_a_horizontal_strand_twists_over_beyond_what_its_twist_holds():
    """Horizontal strands of 2.5 and 3.5 l_b, pushed sideways at 0.1 mm/s at the tip: after 4 s the
    first is still within 1e-4 of its length, the second has turned over beyond 1% (and keeps going);
    only the second is flagged. No segment is compressed: the bending-only test called both stable."""
    from dftl_warp.solvers.elastic_stability import _constrained

    moved = {}
    for ratio in (2.5, 3.5):
        s = np.linspace(0.0, ratio * LB, N + 1)
        pts = np.stack([s, np.zeros_like(s), np.zeros_like(s)], -1)
        grp = rod_group(pts)
        Hb, Hg, _, _ = _constrained(grp, np.arange(1))
        assert np.linalg.eigvalsh(Hb + Hg)[0, 0] > 0 and (grp.T_rest[:, 1:] >= -1e-12).all()
        model = dw.Model.from_strands(pts, [N + 1], precision="float64")
        solver = dw.make_solver(model, "elastic", radius=R)
        state, control = solver.state(), model.control()
        push = np.zeros((N + 1, 3))
        push[:, 2] = 1e-4 * s / s[-1]
        state.write("velocities", model.points_to_device(push, relative=False))
        flagged, _, tested, total = solver.unstable_strands()
        assert tested == total == 1 and flagged.tolist() == ([0] if ratio > 3 else [])
        for _ in range(96):
            solver.advance(state, control, 1.0 / (24 * 8), 8)
        moved[ratio] = np.linalg.norm(model.points_from_device(state.positions)[-1] - pts[-1]) / (ratio * LB)
    assert moved[2.5] < 1e-4 and moved[3.5] > 1e-2, moved


def test_a_costly_groom_is_tested_on_a_sample_within_the_budget():
    """The test's cost grows as the cube of the segments: 64-segment strands cost 8 of the budget's
    32-segment units each, so a budget of 20 tests 2 of 5 standing columns (all unstable)."""
    n = 64
    rest = np.stack([column(2.5 * LB, n) + [0.01 * k, 0, 0] for k in range(5)])
    grp = elastic_rest.RodGroup(rest, np.full((5, n + 1), R), E=HAIR_E, G=TWIST_G, rho=HAIR_DENSITY,
                                gravity=(0.0, -G0, 0.0), inverse_statics=True)
    flagged, scales, tested, total = unstable_strands([(n + 1, np.arange(10, 15), grp)], budget=20)
    assert (tested, total) == (2, 5) and flagged.size == 2 and set(flagged) <= set(range(10, 15))
    assert np.allclose(scales, (2.5 / GREENHILL) ** 3, rtol=5e-3)


def test_one_long_strand_does_not_stop_the_test_of_the_others():
    """A strand whose test alone costs more than the budget (500 segments: (500/32)^3 = 3815 units
    of 2500) is left out, and the others are still tested, whatever the random order: before, the
    sample was the prefix of the random order within the budget, so a long strand drawn first left
    every standing column untested (and ``simulate`` silent)."""
    n = 32
    rest = np.stack([column(2.5 * LB, n) + [0.01 * k, 0, 0] for k in range(4)])
    columns = elastic_rest.RodGroup(rest, np.full((4, n + 1), R), E=HAIR_E, G=TWIST_G, rho=HAIR_DENSITY,
                                    gravity=(0.0, -G0, 0.0), inverse_statics=True)
    long = rod_group(column(0.3, 500) * [1, -1, 1])                  # a long strand hanging straight down
    groups = [(n + 1, np.arange(4), columns), (501, np.array([4]), long)]
    for seed in range(8):
        flagged, _, tested, total = unstable_strands(groups, seed=seed)
        assert (tested, total) == (4, 5) and flagged.tolist() == [0, 1, 2, 3], (seed, flagged, tested)


def test_simulate_names_strands_too_long_to_check(tmp_path, capsys):
    """Strands of more than 434 segments are not checked (the cost grows as the cube of the
    segments); ``simulate`` says so in one line naming the prim, instead of nothing."""
    from usd_stages import add_curves, new_stage

    from dftl_warp import cli

    stage = new_stage(tmp_path / "in.usda", start=1, end=2)
    add_curves(stage, "/World/Long", column(0.3, 500) * [1, -1, 1], [501], widths=2 * R, bending=None)
    add_curves(stage, "/World/Short", column(2.5 * LB) + [0.01, 0, 0], [N + 1], widths=2 * R, bending=None)
    stage.Save()
    assert cli.main(["simulate", str(tmp_path / "in.usda"), "-o", str(tmp_path / "out.usdc")]) == 0
    err = capsys.readouterr().err
    lines = [line for line in err.splitlines() if "not checked for a stable rest shape" in line]
    assert len(lines) == 1 and "/World/Long: 1 strand of more than 434 segments (up to 500)" in lines[0], err
    assert "/World/Short: 1 of the 1 strand checked rests in an unstable equilibrium" in err, err


def _mohawk_scaled(tmp_path, scale, interpolation):
    """Two standing columns of 2.5 l_b and one hanging, with ``primvars:dftl:bendStiffnessScale``."""
    from pxr import Sdf, UsdGeom
    from usd_stages import add_curves, new_stage

    stage = new_stage(tmp_path / "in.usda", start=1, end=2)
    tall = column(2.5 * LB)
    curves = add_curves(stage, "/World/Mohawk", np.concatenate([tall, tall + [0.01, 0, 0], tall * [1, -1, 1] + [0.02, 0, 0]]),
                        [N + 1] * 3, widths=2 * R, bending=None)
    pv = UsdGeom.PrimvarsAPI(curves.GetPrim()).CreatePrimvar("dftl:bendStiffnessScale", Sdf.ValueTypeNames.FloatArray,
                                                             interpolation)
    pv.Set([float(s) for s in np.atleast_1d(scale)])
    stage.Save()
    return tmp_path / "in.usda"


def test_simulate_gives_the_scale_to_author_where_one_is_authored(tmp_path, capsys):
    """The advice is the primvar's value that holds them, not a factor on the authored one: with 1.5
    authored, 1.99 holds the 2.5 l_b columns, as without it (before: '1.33 holds half of them, 1.33
    all', below the 1.5 already authored; Ratboy with 10 authored was told 4.38 holds all)."""
    from dftl_warp import cli

    path = _mohawk_scaled(tmp_path, 1.5, "constant")
    assert cli.main(["simulate", str(path), "-o", str(tmp_path / "out.usdc")]) == 0
    err = capsys.readouterr().err
    assert ("/World/Mohawk: 2 of the 3 strands rest in an unstable equilibrium" in err
            and "primvars:dftl:bendStiffnessScale of 1.99 holds half of them, 1.99 all" in err), err


def test_simulate_gives_a_factor_on_an_authored_ramp(tmp_path, capsys):
    """A ramp varying along the strand has no one value that holds it: the line gives the factor on
    the authored primvar, and says so."""
    from dftl_warp import cli

    ramp = np.tile(np.linspace(1.0, 0.5, N + 1), 3)
    path = _mohawk_scaled(tmp_path, ramp, "vertex")
    assert cli.main(["simulate", str(path), "-o", str(tmp_path / "out.usdc")]) == 0
    err = capsys.readouterr().err
    line = next(x for x in err.splitlines() if "unstable equilibrium" in x)
    assert "a factor on the authored primvars:dftl:bendStiffnessScale of " in line and "holds half of them" in line, err


def test_the_sample_is_the_strands_whatever_the_grouping(monkeypatch):
    """A groom beyond the budget is tested on a random sample of its strands, and the sample is the
    same whether its rods are one group, groups of a few strands (``build`` cuts large grooms into
    groups built on threads) or the parts of a groom split over devices: candidates are drawn in input
    strand order. The chunked build's arrays are those of one group, value for value."""
    n = 64
    rng = np.random.default_rng(4)
    rest = np.stack([column(rng.uniform(0.5, 3.0) * LB, n) + [0.01 * k, 0, 0] for k in range(9)])
    counts = np.full(9, n + 1)
    points = rest.reshape(-1, 3)
    slots = np.arange(points.shape[0])
    kw = dict(E=HAIR_E, G=TWIST_G, rho=HAIR_DENSITY, gravity=(0.0, -G0, 0.0), inverse_statics=True)
    whole = elastic_rest.build(points, counts, slots, np.arange(9), points.shape[0], np.full(points.shape[0], R), **kw)
    monkeypatch.setattr(elastic_rest, "CHUNK_STRANDS", 2)
    cut = elastic_rest.build(points, counts, slots, np.arange(9), points.shape[0], np.full(points.shape[0], R), **kw)
    assert len(whole[2]) == 1 and len(cut[2]) == 5
    for name in whole[0]:
        assert np.array_equal(whole[0][name], cut[0][name]), name
    for name in whole[1]:
        assert np.array_equal(whole[1][name], cut[1][name]), name
    results = [unstable_strands(groups, budget=24, seed=3) for groups in (whole[2], cut[2], cut[2][::-1])]
    assert results[0][2:] == (3, 9)                                   # 3 of the 9 fit the budget of 24
    for flagged, scales, tested, total in results[1:]:
        assert np.array_equal(flagged, results[0][0]) and (tested, total) == (3, 9)
        assert np.allclose(scales, results[0][1])
    assert results[0][0].size > 0                                     # some of the sample stand unstably
