"""Clean starts on a CT-scan-like head: an irregular closed mesh (a noisy, lumpy sphere) with hair
rooted on it, some strands starting inside. After the clean start and a preroll, nothing
penetrates the contact distance by more than 1% of the hair radius, and the shot has no pop."""

import numpy as np
import pytest
from pxr import Usd

import dftl_warp as dw
from dftl_warp import features as F
from dftl_warp.features.clean_start import _depths, measure_start, preroll, resolve_start

R, HAIR_RADIUS, FPS, SUBSTEPS = 0.1, 0.0005, 24.0, 10


def lumpy_sphere(nu=48, nv=96, seed=3):
    rng = np.random.default_rng(seed)
    th = np.linspace(0, np.pi, nu + 1)[1:-1]
    ph = np.linspace(0, 2 * np.pi, nv, endpoint=False)
    t, p = np.meshgrid(th, ph, indexing="ij")
    lump = (0.06 * np.sin(3 * t) * np.cos(2 * p) + 0.04 * np.sin(5 * p + 1.0) * np.sin(t) ** 2
            + 0.004 * rng.standard_normal(t.shape))
    r = R * (1 + lump)
    pts = np.stack([r * np.sin(t) * np.cos(p), r * np.cos(t), r * np.sin(t) * np.sin(p)], -1).reshape(-1, 3)
    pts = np.concatenate([pts, [[0, R, 0], [0, -R, 0]]])
    top, bottom = len(pts) - 2, len(pts) - 1
    idx = lambda i, j: i * nv + (j % nv)   # noqa: E731
    tris = []
    for j in range(nv):
        tris.append([top, idx(0, j + 1), idx(0, j)])
        tris.append([bottom, idx(nu - 2, j), idx(nu - 2, j + 1)])
        for i in range(nu - 2):
            tris += [[idx(i, j), idx(i, j + 1), idx(i + 1, j)], [idx(i + 1, j), idx(i, j + 1), idx(i + 1, j + 1)]]
    tris = np.array(tris)
    a, b, c = pts[tris[:, 0]], pts[tris[:, 1]], pts[tris[:, 2]]
    if np.einsum("ij,ij->i", a, np.cross(b - a, c - a)).sum() < 0:
        tris = tris[:, ::-1]
    return pts, tris


def groom(pts, n=16, seg=0.004):
    """Strands rooted on the upper vertices; every third one combed into the head."""
    rng = np.random.default_rng(0)
    roots = pts[(pts[:, 1] > 0.3 * R) & (np.arange(len(pts)) % 5 == 0)]
    strands = []
    for k, root in enumerate(roots):
        normal = root / np.linalg.norm(root)
        tangent = np.cross(normal, rng.normal(size=3))
        tangent /= np.linalg.norm(tangent)
        d = tangent - 0.35 * normal if k % 3 == 0 else normal + tangent
        d /= np.linalg.norm(d)
        strands.append(root + np.arange(n)[:, None] * seg * d)
    return np.concatenate(strands), np.full(len(roots), n)


def setup():
    pts, tris = lumpy_sphere()
    points, counts = groom(pts)
    model = dw.Model.from_strands(points, counts, widths=2 * HAIR_RADIUS, device="cpu",
                                  features=[F.Colliders([F.TriangleMesh(points=pts, indices=tris, friction=0.3)])])
    solver = dw.DFTLSolver(model, gravity=(0, -9.81, 0))
    return model, solver, solver.state(), model.control(), points, counts


def test_clean_start_moves_hair_out_and_reports():
    model, solver, state, control, points, counts = setup()
    before = measure_start(model, state, control)
    assert before.inside > 20 and before.max_depth > 10 * HAIR_RADIUS
    assert "started inside a collider" in before.line() and f"{before.inside} of" in before.line()
    rest = model.points_from_device(state.positions.numpy())
    report = resolve_start(model, state, control)
    assert report.inside == before.inside
    after = measure_start(model, state, control)
    assert after.max_penetration <= 0.01 * HAIR_RADIUS
    x = model.points_from_device(state.positions.numpy())
    starts = np.concatenate([[0], np.cumsum(counts)])
    seg = np.linalg.norm(np.diff(x, axis=0), axis=1)
    seg_rest = np.linalg.norm(np.diff(rest, axis=0), axis=1)
    inner = np.ones(len(seg), bool)
    inner[starts[1:-1] - 1] = False       # pairs across strands
    assert np.abs(seg[inner] - seg_rest[inner]).max() < 1e-5 * 0.004 * 10
    assert np.allclose(x[starts[:-1]], points[starts[:-1]], atol=1e-6)   # roots untouched
    # a strand with no particle in contact is left exactly as it was, not re-placed at its rest
    # lengths (round-off that made a groom split over devices start otherwise than on one)
    pen, _, valid = _depths(model, solver.state(), control)
    free = np.zeros(len(counts), bool)
    free[model.layout.strand_order] = ~np.any(valid & (pen > 0), axis=1)
    assert 5 < free.sum() < len(counts)
    strand = np.repeat(np.arange(len(counts)), counts)
    assert x[free[strand]].tobytes() == rest[free[strand]].tobytes()


def ease(frame, shift=0.04, frames=24):
    """The head's sideways offset (m) at ``frame`` after the preroll: smoothstep over ``frames``."""
    t = min(max(frame / frames, 0.0), 1.0)
    return shift * t * t * (3 - 2 * t)


def test_preroll_settles_without_penetration_or_pop():
    model, solver, state, control, points, counts = setup()
    roots = points[np.concatenate([[0], np.cumsum(counts)[:-1]])]
    control.set_root_targets(roots, roots)
    report = preroll(solver, state, control, 1.0, 1 / FPS, SUBSTEPS)
    assert report.frames >= 24 and report.settled, report.line()
    assert report.motion <= HAIR_RADIUS and "settled" in report.line()
    after = measure_start(model, state, control)
    assert after.max_penetration <= 0.01 * HAIR_RADIUS      # <= 1% of the hair radius beyond contact
    assert np.abs(state.velocities.numpy()).max() == 0.0
    # the shot: the head eases sideways (roots and mesh together); the largest per-frame
    # displacement over the first 3 frames is no larger than over the frames that follow
    x0 = model.points_from_device(state.positions.numpy())
    moved = []
    for f in range(24):
        a, b = ease(f), ease(f + 1)
        control.features.set_collider_poses(np.array([[a, 0, 0, 0, 0, 0, 1.0]]), np.array([[b, 0, 0, 0, 0, 0, 1.0]]))
        control.set_root_targets(roots + [a, 0, 0], roots + [b, 0, 0])
        solver.advance(state, control, 1 / FPS / SUBSTEPS, SUBSTEPS)
        x = model.points_from_device(state.positions.numpy())
        moved.append(np.linalg.norm(x - x0, axis=1).max())
        x0 = x
    assert max(moved[:3]) <= max(moved[3:]), np.round(np.array(moved) * 1e3, 2)


def test_simulate_cli_moves_hair_out_of_a_sphere_and_prerolls(tmp_path, capsys):
    """dftl-warp simulate: strands combed into a sphere collider come out before frame 1, the report
    line names how many particles and how deep, and --preroll 0.5 starts the shot settled: the
    groom moves less than the settling tolerance (the hair radius per frame) into the shot."""
    from usd_stages import add_curves, chain, composed_samples, new_stage
    from test_usd_features import sphere_collider

    from dftl_warp import cli

    stage = new_stage(tmp_path / "in.usda", start=1, end=3)
    d = np.array([1.0, -1.0, 0.0]) / np.sqrt(2)
    pts = np.concatenate([chain(12, 0.01, direction=d, origin=(0.0, 0.1, z)) for z in (-0.02, 0.0, 0.02)])
    add_curves(stage, "/World/Hair", pts, [12, 12, 12], widths=0.002)
    sphere_collider(stage, "/World/Ball", 0.1)
    stage.Save()
    radius = 0.001
    out = tmp_path / "out.usdc"
    assert cli.main(["simulate", str(tmp_path / "in.usda"), "-o", str(out), "--substeps", "10",
                     "--preroll", "0.5"]) == 0
    err = capsys.readouterr().err
    line = next(w for w in err.splitlines() if w.startswith("dftl-warp: warning: clean start:"))
    inside = int(line.split("clean start: ")[1].split(" of ")[0])
    deep = float(line.split("up to ")[1].split(" m deep")[0])
    assert inside > 10 and 0.01 < deep < 0.1, line
    assert " of 33 free particles (roots excluded) started inside" in line, line   # info counts the 36 with roots
    assert "preroll: " in err and ", settled" in err, err
    # each line once, before the run (they were repeated after it as "warning:")
    assert sum("clean start: " in w for w in err.splitlines()) == 1, err
    assert sum("preroll: " in w for w in err.splitlines()) == 1, err
    samples = composed_samples(out, "/World/Hair")
    velocities = composed_samples(out, "/World/Hair", "velocities")
    first, second = samples[1.0], samples[2.0]
    assert (np.linalg.norm(first, axis=1)[np.arange(36) % 12 > 0] >= 0.1 + radius * 0.99).all()
    assert np.allclose(first[::12], pts[::12], atol=1e-6)                   # roots where authored
    assert np.abs(velocities[1.0]).max() == 0.0
    assert np.linalg.norm(second - first, axis=1).max() <= radius          # settled into the shot
    assert np.linalg.norm(velocities[2.0], axis=1).max() <= radius * 24.0


def test_hair_the_push_out_cannot_free_is_named_in_one_line(tmp_path):
    """A strand rooted 5 cm inside a sphere: the particle next to its root has 1 cm of rest length
    to leave by and stays 4 cm inside (the roots are kinematic), so the clean start says so in one
    line naming the prim, strand (second of the prim, after a clean one; a second prim before it in
    the same group) and point, with the depth that frame 1's penetration QC measures: (r + depth) / r.
    Strands combed into the sphere from outside come out and are not named."""
    from usd_stages import add_curves, chain, new_stage
    from test_usd_features import sphere_collider

    from dftl_warp.output.qc import ATTRIBUTES
    from dftl_warp.simulation.simulate import simulate_usd

    stage = new_stage(tmp_path / "in.usda", start=1, end=2)
    d = np.array([1.0, -1.0, 0.0]) / np.sqrt(2)
    combed = [chain(12, 0.01, direction=d, origin=(0.0, 0.1, z)) for z in (-0.02, 0.02)]
    add_curves(stage, "/World/Fur", np.concatenate(combed), [12, 12], widths=0.002)
    held = [chain(12, 0.01, direction=(0.0, 1.0, 0.0), origin=o) for o in ((0.3, 0.3, 0.0), (0.0, 0.05, 0.0))]
    add_curves(stage, "/World/Hair", np.concatenate(held), [12, 12], widths=0.002)
    sphere_collider(stage, "/World/Ball", 0.1)
    stage.Save()
    out = tmp_path / "out.usdc"
    summary = simulate_usd(tmp_path / "in.usda", out, device="cpu", substeps=4)
    lines = [w for w in summary.start_notes if "still inside" in w]
    assert len(lines) == 1, summary.start_notes
    assert "at /World/Hair strand 1, point 1:" in lines[0] and "5 particles of 1 strand are" in lines[0], lines[0]
    assert lines[0] in summary.warnings
    deep = float(lines[0].split("up to ")[1].split(" m deep")[0])
    radii = float(lines[0].split("deep (")[1].split(" hair radii")[0])
    assert deep == pytest.approx(0.04, rel=1e-3) and radii == pytest.approx(deep / 0.001, rel=1e-3)
    written = Usd.Stage.Open(str(out))
    qc = written.GetPrimAtPath("/dftl_qc/World_Hair").GetAttribute(ATTRIBUTES["penetration"])
    assert qc.Get(1.0) == pytest.approx(1.0 + radii, rel=1e-3)
    # without the held strand everything comes out, and nothing is named
    stage = new_stage(tmp_path / "clean.usda", start=1, end=2)
    add_curves(stage, "/World/Fur", np.concatenate(combed), [12, 12], widths=0.002)
    sphere_collider(stage, "/World/Ball", 0.1)
    stage.Save()
    summary = simulate_usd(tmp_path / "clean.usda", tmp_path / "clean.usdc", device="cpu", substeps=4)
    assert any("started inside a collider" in w for w in summary.start_notes), summary.start_notes
    assert not any("still inside" in w for w in summary.start_notes), summary.start_notes


def test_hair_without_width_moved_onto_a_surface_is_not_still_inside():
    """Hair without widths (radius 0) pushed out of a mesh sits on its surface to float32 round-off
    (1e-8 m here): that is no penetration, and the clean start named it as hair still inside."""
    from dftl_warp.features.clean_start import _depths, still_inside

    rng = np.random.default_rng(1)
    pts, tris = lumpy_sphere()
    roots = pts[rng.choice(len(pts), 200)]
    strands = []
    for root in roots:
        d = -root / np.linalg.norm(root) + rng.normal(scale=0.3, size=3)
        strands.append(root * 1.001 + np.arange(12)[:, None] * 0.004 * d / np.linalg.norm(d))
    model = dw.Model.from_strands(np.concatenate(strands), np.full(200, 12), device="cpu",
                                  features=[F.Colliders([F.TriangleMesh(points=pts, indices=tris, friction=0.3)])])
    state, control = dw.DFTLSolver(model, gravity=(0, -9.81, 0)).state(), model.control()
    assert resolve_start(model, state, control).inside > 1000
    pen, rad, valid = _depths(model, state, control)
    on_surface = valid & (pen > 0)
    assert on_surface.any() and pen[on_surface].max() < 1e-7          # round-off on the surface
    assert still_inside(model, state, control)[0].size == 0
    assert measure_start(model, state, control).inside == 0
