"""The hair-hair repulsion does not depend on how many strands or vertices represent the hair (CPU).

The grid's density was once a count of particles, so the same hair drawn with 4 times the strands
pushed 4 times harder: a 1M-strand groom was pushed at up to 700 g where its 100k-strand version
was pushed at 70 g (docs/features.md). Each particle now splats its hair volume (its width and
Voronoi length) over the groom's typical volume fraction at rest, so the density is 1 where the
hair is as dense as it typically is at rest, and the repulsion is an acceleration per unit of that
relative density across a cell."""

from __future__ import annotations

import numpy as np
import pytest

import dftl_warp as dw
from dftl_warp import features as F
from dftl_warp.features.hair_hair import rest_density, rest_peak, volume_fractions

CELL = 0.01


def slab(copies: int, width: float, side: int = 30, spacing: float = 0.002):
    """Pendulums (a root and one free particle 5 mm below it) in a square slab of ``side`` x ``side``
    positions ``spacing`` apart, each drawn ``copies`` times (1 um apart) with hair ``width``."""
    pts = []
    for i in range(side):
        for j in range(side):
            for c in range(copies):
                root = np.array([i * spacing + 1e-6 * c, 0.0, j * spacing])
                pts += [root, root + [0.0, -0.005, 0.0]]
    return np.array(pts), np.full(side * side * copies, 2), width


def push(pts, counts, width, repulsion=5.0, splat="strands"):
    """The free particles' acceleration (m/s^2) in one substep without gravity or friction: the
    repulsion alone (of all the density: threshold 0), and their x positions."""
    model = dw.Model.from_strands(pts, counts, precision="float64", widths=width,
                                  features=[F.HairHair(cell_size=CELL, friction=0.0, repulsion=repulsion,
                                                       splat=splat, threshold=0.0)])
    solver = dw.DFTLSolver(model, gravity=(0.0, 0.0, 0.0), fused=False)
    state, control = solver.state(), model.control()
    dt = 1e-4
    solver.step(state, state, control, dt, 1.0)
    v = model.points_from_device(state.velocities, relative=False)[1::2]
    return v / dt, pts[1::2]


@pytest.mark.parametrize("splat", ["strands", "particles"])
def test_four_times_the_strands_a_quarter_as_thick_push_alike(splat):
    a1, x = push(*slab(1, 80e-6), splat=splat)
    a4, _ = push(*slab(4, 40e-6), splat=splat)
    a4 = a4[::4]                              # the first copy of each pendulum
    edge = np.argmax(np.linalg.norm(a1, axis=1))
    assert np.linalg.norm(a1[edge]) > 0.5     # the repulsion acts
    # alike up to each particle's own share, which it does not feel: a whole pendulum's in one slab,
    # a quarter of it in the other (its 3 twins push it); with particle counts for density, the
    # second slab pushed 4 times harder
    np.testing.assert_allclose(a4, a1, atol=0.05 * np.abs(a1).max())


def test_the_edge_of_a_groom_at_rest_is_pushed_at_about_the_repulsion():
    """Inside a uniform slab the relative density is about 1 and flat; across its edge it falls to
    0 within about a cell, so the hair there is pushed outward at about ``repulsion``, whatever the
    strand count."""
    for copies, width in ((1, 80e-6), (4, 80e-6), (9, 20e-6)):
        a, x = push(*slab(copies, width), repulsion=5.0)
        a = a[::copies]
        x = x[::copies]
        largest = np.abs(a[:, 0]).max()
        assert 1.0 < largest < 10.0, (copies, largest)
        centre = np.abs(x[:, 0] - x[:, 0].mean()) < 0.01
        edge = np.abs(x[:, 0] - x[:, 0].mean()) > 0.025
        assert np.abs(a[centre, 0]).max() < 0.5 * largest
        # outward at both edges
        assert (np.sign(a[edge, 0]) == np.sign(x[edge, 0] - x[:, 0].mean())).mean() > 0.9


def test_refined_strands_splat_the_same_volume():
    """Twice the vertices along the same strands: each particle carries half the length, and the
    rest density (the density a particle sits in) is the same."""
    rng = np.random.default_rng(3)
    roots = rng.uniform(-0.03, 0.03, (40, 3))
    coarse = np.concatenate([r + np.outer(np.arange(9), [0.003, -0.004, 0.0]) for r in roots])
    fine = np.concatenate([r + np.outer(np.arange(17) * 0.5, [0.003, -0.004, 0.0]) for r in roots])
    phi_c = volume_fractions(coarse, [9] * 40, None, CELL)
    phi_f = volume_fractions(fine, [17] * 40, None, CELL)
    assert phi_f.sum() == pytest.approx(phi_c.sum(), rel=1e-12)   # the same hair volume
    assert rest_density(fine, phi_f, CELL) == pytest.approx(rest_density(coarse, phi_c, CELL), rel=0.05)


def test_a_point_without_width_counts_as_human_hair():
    pts = np.array([[0.0, 0.0, 0.0], [0.0, -0.01, 0.0], [0.0, -0.02, 0.0]])
    none = volume_fractions(pts, [3], None, CELL)
    zero = volume_fractions(pts, [3], np.array([0.0, 0.0, 80e-6]), CELL)
    np.testing.assert_allclose(zero, none, rtol=1e-15)
    # the middle point carries a whole segment of 80 um hair
    assert none[1] == pytest.approx(np.pi * 40e-6 ** 2 * 0.01 / CELL ** 3, rel=1e-12)


def test_usd_defaults_are_si_values_in_stage_units():
    """On a stage in centimetres the default repulsion (5 m/s^2) is 500 cm/s^2 and hair without
    widths is 80 um = 0.008 cm wide."""
    from dftl_warp.features import features_from_attributes

    (hh,) = features_from_attributes({"dftl:hairHair": True}, [{}], [1], mean_segment=1.0, meters_per_unit=0.01)
    assert hh.repulsion == pytest.approx(500.0)
    assert hh.hair_width == pytest.approx(0.008)


def test_hair_outside_a_smaller_grid_is_left_out_of_the_rest_density():
    """A grid ``extent`` smaller than the hair (threshold 0, so the slab at rest is pushed): the hair
    outside it is neither splatted nor pushed,
    so the rest density is the hair's inside it, and the slab inside is pushed as it is alone. The
    rest density's numpy splat spanned the whole hair (a slab and its copy 1 km away: 10^15 nodes,
    a MemoryError); now it is no larger than the device grid."""
    import tracemalloc

    pts, counts, width = slab(1, 80e-6)
    far = pts + [1000.0, 0.0, 1000.0]
    extent = np.array([0.1, 0.1, 0.1])

    def accelerations(points, n):
        model = dw.Model.from_strands(points, np.full(n, 2), precision="float64", widths=width,
                                      features=[F.HairHair(cell_size=CELL, friction=0.0, extent=extent,
                                                           threshold=0.0)])
        solver = dw.DFTLSolver(model, gravity=(0.0, 0.0, 0.0), fused=False)
        state = solver.state()
        solver.step(state, state, model.control(), 1e-4, 1.0)
        return model.points_from_device(state.velocities, relative=False)[1::2] / 1e-4

    alone = accelerations(pts, len(counts))
    tracemalloc.start()
    both = accelerations(np.concatenate([pts, far]), 2 * len(counts))
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    assert peak < 100e6, peak
    assert np.abs(alone).max() > 0.5                      # the repulsion acts
    np.testing.assert_allclose(both[:len(counts)], alone, rtol=1e-9, atol=1e-9)
    np.testing.assert_array_equal(both[len(counts):], 0.0)   # outside the grid: nothing


def test_a_grid_of_too_many_nodes_is_refused_in_one_line(tmp_path, capsys):
    """Two tufts 20 km apart on 4 cm cells: 2.5e12 nodes. simulate and info refuse it in one line
    naming the file and max_cells, before anything is allocated (simulate's rest density splatted
    the whole box first: a MemoryError traceback for 1.75 TiB here, killed by the kernel at 24 GB
    for tufts 2 km apart; info gave a ValueError traceback)."""
    import tracemalloc

    from usd_stages import add_curves, new_stage, set_attr

    from dftl_warp import cli

    path = tmp_path / "far.usda"
    stage = new_stage(path, end=2)
    for k, offset in enumerate([(0.0, 0.0, 0.0), (20000.0, 0.0, 20000.0)]):
        tuft = [np.array(offset) + [0.002 * s, 0.0, 0.0] + np.outer(np.arange(10), [0.0, -0.01, 0.0])
                for s in range(20)]
        add_curves(stage, f"/World/Tuft{k}", np.concatenate(tuft), [10] * 20)
    set_attr(stage.GetPrimAtPath("/World"), "dftl:hairHair", "Bool", True)
    stage.GetRootLayer().Save()
    out = tmp_path / "out.usdc"
    for argv in (["simulate", str(path), "-o", str(out), "--device", "cpu", "--quiet"], ["info", str(path)]):
        tracemalloc.start()
        code = cli.main(argv)
        peak = tracemalloc.get_traced_memory()[1]
        tracemalloc.stop()
        err = capsys.readouterr().err.strip().splitlines()
        assert code == 2, (argv, err)
        assert len(err) == 1 and "Traceback" not in err[0], err
        assert err[0].startswith(f"dftl-warp: error: {path}: hair-hair grid of "), err
        assert "exceeds max_cells=16777216" in err[0]
        assert peak < 200e6, (argv, peak)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["far.usda"]


def test_info_prints_the_grid_simulate_sets_up(tmp_path, capsys):
    """`info` gives each group's hair-hair cell, repulsion (stage units and m/s^2) and rest volume
    fraction, the one simulate weighs the particles against (20 strands of 80 um hair 2 mm apart on
    4 cm cells: a few 1e-5)."""
    from pxr import Sdf
    from usd_stages import add_curves, chain, new_stage

    from dftl_warp import cli
    from dftl_warp.features.hair_hair import group_rest_statistics

    path = tmp_path / "hh.usda"
    stage = new_stage(path, start=1, end=4, meters_per_unit=0.01)
    pts = np.concatenate([chain(10, 1.0, direction=(0, -1, 0), origin=(0.2 * k, 0, 0)) for k in range(20)])
    add_curves(stage, "/World/Hair", pts, [10] * 20, widths=0.008)
    stage.GetPrimAtPath("/World").CreateAttribute("dftl:hairHair", Sdf.ValueTypeNames.Bool, custom=True).Set(True)
    stage.Save()
    assert cli.main(["info", str(path)]) == 0
    lines = [line for line in capsys.readouterr().out.splitlines() if line.strip().startswith("hair-hair")]
    assert len(lines) == 1, lines
    want, _ = group_rest_statistics(F.HairHair(cell_size=4.0, hair_width=0.008), pts, [10] * 20, 0.008)
    assert "/World/Hair: cell 4 units, repulsion 500 units/s^2 (5 m/s^2)" in lines[0], lines
    assert f"rest volume fraction {want:.3g}" in lines[0] and 1e-5 < want < 1e-4, (lines, want)
    # the threshold, not authored, is the densest node at rest (the hair at rest is not pushed)
    _, peak = group_rest_statistics(F.HairHair(cell_size=4.0, hair_width=0.008), pts, [10] * 20, 0.008)
    assert f"densest node at rest {peak:.3g}; threshold {peak:.3g}, the densest node at rest by default)" in lines[0]
    stage.GetPrimAtPath("/World").CreateAttribute("dftl:hairHairThreshold", Sdf.ValueTypeNames.Float,
                                                  custom=True).Set(0.0)
    stage.Save()
    assert cli.main(["info", str(path)]) == 0
    out = capsys.readouterr().out
    assert f"densest node at rest {peak:.3g}; threshold 0)" in out, out


def test_a_threshold_at_the_rest_peak_leaves_a_groom_at_rest_alone_and_pushes_compressed_hair():
    """Only hair packed denser than ``threshold`` pushes. The uniform slab at rest is pushed out at
    its edge by about the repulsion with threshold 0, and not at all with the threshold at its
    densest node at rest (1.42 times its typical density); the same slab squeezed to half its
    spacing (4 times as dense) is pushed with it, as with the default threshold (None: the model's
    densest node at rest)."""
    pts, counts, width = slab(1, 80e-6)
    typical = rest_density(pts, volume_fractions(pts, counts, width, CELL), CELL)
    peak = rest_peak(pts, volume_fractions(pts, counts, width, CELL), CELL)
    assert 1.2 < peak < 1.6, peak

    def largest(points, threshold):
        model = dw.Model.from_strands(points, counts, precision="float64", widths=width,
                                      features=[F.HairHair(cell_size=CELL, friction=0.0, repulsion=5.0,
                                                           threshold=threshold, rest_density=typical)])
        solver = dw.DFTLSolver(model, gravity=(0.0, 0.0, 0.0), fused=False)
        state, control = solver.state(), model.control()
        solver.step(state, state, control, 1e-4, 1.0)
        return np.abs(model.points_from_device(state.velocities, relative=False)[1::2, [0, 2]]).max() / 1e-4

    free, held = largest(pts, 0.0), largest(pts, peak)
    assert free > 1.0 and held < 1e-6 * free, (free, held)
    assert largest(pts, None) < 1e-6 * free     # the default threshold: the densest node at rest
    centre = pts.reshape(-1, 2, 3)[:, :1].mean(0)
    squeezed = centre + (pts - centre) * np.array([0.5, 1.0, 0.5])
    assert largest(squeezed, peak) > 0.5 * free
    # the squeezed slab's own densest node is its rest: the default measures the model's rest
    assert largest(squeezed, None) < 1e-6 * free


def test_a_negative_threshold_is_one_line_naming_the_attribute(tmp_path, capsys):
    from pxr import Sdf
    from usd_stages import add_curves, chain, new_stage

    from dftl_warp import cli

    path = tmp_path / "hh.usda"
    stage = new_stage(path, start=1, end=2)
    add_curves(stage, "/World/Hair", chain(5, 0.01), [5])
    world = stage.GetPrimAtPath("/World")
    world.CreateAttribute("dftl:hairHair", Sdf.ValueTypeNames.Bool, custom=True).Set(True)
    world.CreateAttribute("dftl:hairHairThreshold", Sdf.ValueTypeNames.Float, custom=True).Set(-1.0)
    stage.Save()
    assert cli.main(["simulate", str(path), "-o", str(tmp_path / "out.usdc")]) != 0
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "dftl:hairHairThreshold" in err[0] and str(path) in err[0], err
    assert not (tmp_path / "out.usdc").exists()
