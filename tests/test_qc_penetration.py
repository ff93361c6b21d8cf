"""Per-frame QC: collider penetration (issue 21, docs/caches.md).

``penetration`` = max over a prim's particles (roots excepted) of max(0, r - d) / r, ``d`` the
signed distance to the nearest collider surface, ``r`` the hair radius (the colliders' contact
distance). Checked against closed-form distances for every registered shape, against a host
computation on written frames of hair draped on a sphere, and through ``--check`` / ``batch``."""

import numpy as np
import pytest
from pxr import Usd
from usd_stages import add_curves, chain, composed_samples, new_stage

from dftl_warp import cli
from dftl_warp import features as F
from dftl_warp.core.model import Model
from dftl_warp.features.colliders import Ellipsoid
from dftl_warp.output.qc import ATTRIBUTES, prim_penetration
from dftl_warp.simulation.simulate import simulate_usd

R_HAIR = 0.002       # hair radius (m) of most particles
UNIT = 0.001         # the depth unit of particles without width (m)
FAR = (5.0, 5.0, 5.0)


def cube_mesh(h):
    """Closed cube [-h, h]^3, 12 triangles wound counter-clockwise seen from outside."""
    p = np.array([[x, y, z] for x in (-h, h) for y in (-h, h) for z in (-h, h)], dtype=np.float64)
    quads = [[0, 1, 3, 2], [4, 6, 7, 5], [0, 4, 5, 1], [2, 3, 7, 6], [0, 2, 6, 4], [1, 5, 7, 3]]
    tris = np.array([t for a, b, c, d in quads for t in ((a, b, c), (a, c, d))])
    return p, tris


CUBE_POINTS, CUBE_TRIANGLES = cube_mesh(0.1)
SHAPES = [   # user order: the poses below follow it
    F.Sphere(radius=0.1, position=(0.0, 0.0, 0.0)),
    F.Sphere(radius=0.05, position=(0.12, 0.0, 0.0)),                 # overlaps the first
    F.Capsule(radius=0.05, half_height=0.1, axis="Z", position=(1.0, 0.0, 0.0)),
    F.Box(half_extents=(0.1, 0.2, 0.3), position=(0.0, 1.0, 0.0)),
    Ellipsoid(radii=(0.2, 0.1, 0.05), position=(1.0, 1.0, 0.0)),
    F.TriangleMesh(points=CUBE_POINTS, indices=CUBE_TRIANGLES, position=(0.0, 0.0, 1.0)),
]

# strands (prims): [(point, hair radius)], the first the root; and the expected penetration,
# (r - d) / r of the deepest particle from its closed-form signed distance d
CASES = [
    ("sphere, 4 mm deep", [(FAR, R_HAIR), ((0.0, 0.096, 0.0), R_HAIR), (FAR, R_HAIR)], (R_HAIR + 0.004) / R_HAIR),
    ("sphere, within the contact distance", [(FAR, R_HAIR), ((0.0, 0.0, -0.1015), R_HAIR)], (R_HAIR - 0.0015) / R_HAIR),
    ("two spheres: the deeper one, not the sum", [(FAR, R_HAIR), ((0.09, 0.0, 0.0), R_HAIR)], (R_HAIR + 0.02) / R_HAIR),
    ("capsule side", [(FAR, R_HAIR), ((1.047, 0.0, 0.05), R_HAIR)], (R_HAIR + 0.003) / R_HAIR),
    ("box face", [(FAR, R_HAIR), ((0.099, 1.05, 0.1), R_HAIR)], (R_HAIR + 0.001) / R_HAIR),
    ("ellipsoid pole of the smallest axis", [(FAR, R_HAIR), ((1.0, 1.0, 0.048), R_HAIR)], (R_HAIR + 0.002) / R_HAIR),
    ("mesh face", [(FAR, R_HAIR), ((0.099, 0.02, 1.03), R_HAIR)], (R_HAIR + 0.001) / R_HAIR),
    ("mesh, 7 cm deep (20 x its depth band)", [(FAR, R_HAIR), ((0.03, 0.01, 0.98), R_HAIR)],
     (R_HAIR + 0.07) / R_HAIR),
    ("per-vertex radius: the thinner particle",
     [(FAR, R_HAIR), ((0.0, 0.099, 0.0), 0.004), ((0.0, -0.099, 0.0), 0.001)], (0.001 + 0.001) / 0.001),
    ("no width: depth below the surface / unit", [(FAR, 0.0), ((0.0, 0.0, 0.096), 0.0)], 0.004 / UNIT),
    ("root inside is left out", [((0.0, -0.05, 0.0), R_HAIR), ((0.0, -0.3, 0.0), R_HAIR), (FAR, R_HAIR)], 0.0),
    ("outside everything", [(FAR, R_HAIR), ((0.5, 0.5, 0.5), R_HAIR)], 0.0),
]


def build(precision="float32"):
    points = np.array([p for _, strand, _ in CASES for p, _ in strand], dtype=np.float64)
    widths = np.array([2 * r for _, strand, _ in CASES for _, r in strand])
    counts = [len(strand) for _, strand, _ in CASES]
    model = Model.from_strands(points, counts, widths=widths, device="cpu", precision=precision,
                               features=[F.Colliders(SHAPES)])
    return model, points


def measure(model, state, control):
    """Each case its own prim: the member of device strand s is the input strand it holds."""
    member = np.asarray(model.layout.strand_order, dtype=np.int32)
    return prim_penetration(model, state, control, member, len(CASES), UNIT)


def test_penetration_of_every_shape_against_its_closed_form_distance():
    model, points = build()
    got = measure(model, model.state(), model.control())
    expected = np.array([e for _, _, e in CASES])
    for (name, _, _), g, e in zip(CASES, got, expected):
        assert g == pytest.approx(e, rel=2e-4, abs=1e-4), name
    # at a moved pose (all translated, the box turned 90 degrees about z): the same values with
    # the points carried along
    model, points = build()
    state, control = model.state(), model.control()
    shift = np.array([0.3, -0.2, 0.1])
    turn = np.array([0.0, 0.0, np.sin(np.pi / 4), np.cos(np.pi / 4)])
    poses = np.array([np.concatenate([s.position + shift, turn if isinstance(s, F.Box) else s.rotation])
                      for s in SHAPES])
    control.features.set_collider_poses(poses)
    moved = points + shift
    box = int(np.flatnonzero([name == "box face" for name, _, _ in CASES])[0])
    k = sum(len(s) for _, s, _ in CASES[:box]) + 1
    local = points[k] - SHAPES[3].position
    moved[k] = SHAPES[3].position + shift + np.array([-local[1], local[0], local[2]])   # rotated 90 degrees about z
    state.write("positions", model.points_to_device(moved))
    got = measure(model, state, control)
    for (name, _, _), g, e in zip(CASES, got, expected):
        assert g == pytest.approx(e, rel=2e-4, abs=1e-4), f"moved: {name}"


def test_no_colliders_is_zero():
    model = Model.from_strands(chain(4, 0.01), [4], device="cpu")
    assert measure(model, model.state(), model.control())[:1].tolist() == [0.0]


# -- through simulate ----------------------------------------------------------------------------


def sphere(stage, path, radius):
    from pxr import UsdGeom, UsdPhysics

    s = UsdGeom.Sphere.Define(stage, path)
    s.CreateRadiusAttr(radius)
    UsdPhysics.CollisionAPI.Apply(s.GetPrim())


def test_draped_hair_reports_what_the_written_frames_show(tmp_path):
    """Hair dropped onto a sphere (r = 10 cm) and resting on it: the QC of every written frame is
    the host's max(0, r - d) / r over the written points (float32), and under 1%."""
    stage = new_stage(tmp_path / "in.usda", start=1, end=16)
    pts = np.concatenate([chain(10, 0.01, origin=(-0.045, 0.104, z)) for z in (-0.02, 0.0, 0.02)])
    add_curves(stage, "/World/Hair", pts, [10] * 3, widths=2 * R_HAIR)
    sphere(stage, "/World/Ball", 0.1)
    stage.Save()
    out = tmp_path / "out.usdc"
    assert cli.main(["simulate", str(tmp_path / "in.usda"), "-o", str(out), "--substeps", "10", "--quiet",
                     "--device", "cpu", "--solver", "dftl", "--check", "penetration<0.05"]) == 0
    written = Usd.Stage.Open(str(out))
    qc = written.GetPrimAtPath("/dftl_qc/World_Hair").GetAttribute(ATTRIBUTES["penetration"])
    touching = 0
    for t, x in composed_samples(out, "/World/Hair").items():
        d = np.linalg.norm(x, axis=1).reshape(3, 10)[:, 1:] - 0.1
        host = max(0.0, float(((R_HAIR - d) / R_HAIR).max()))
        assert qc.Get(t) == pytest.approx(host, abs=1e-4)   # float32 points of 10 cm: 1e-8 m
        assert 0.0 <= qc.Get(t) < 0.01
        touching += int((d < 1.01 * R_HAIR).sum())
    assert touching > 20   # it does lie on the sphere


def test_check_penetration_exits_3_naming_frame_and_prim(tmp_path, capsys):
    """Roots 5 cm inside a sphere: the particles next to them cannot leave it (their rest length is
    1 cm), so frame 1 breaks ``penetration<0.05`` for /World/Hair (not /World/Fur or /World/Bare,
    outside) by at least (r + 4 cm) / r, and so does every frame; ``batch`` fails the job with the
    same line."""
    from dftl_warp.batch.checkpoint import run_job
    from dftl_warp.batch.jobs import load_jobs

    stage = new_stage(tmp_path / "in.usda", start=1, end=4)
    add_curves(stage, "/World/Fur", chain(8, 0.01, origin=(0.5, 0.5, 0.0)), [8], widths=2 * R_HAIR)
    add_curves(stage, "/World/Bare", chain(8, 0.01, origin=(-0.5, 0.5, 0.0)), [8])
    add_curves(stage, "/World/Hair", chain(12, 0.01, direction=(0.0, 1.0, 0.0), origin=(0.0, 0.05, 0.0)), [12],
               widths=2 * R_HAIR)
    sphere(stage, "/World/Ball", 0.1)
    stage.Save()
    out = tmp_path / "out.usdc"
    code = cli.main(["simulate", str(tmp_path / "in.usda"), "-o", str(out), "--quiet", "--device", "cpu",
                     "--solver", "dftl", "--check", "stretch<1e-3,penetration<0.05"])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 3 and len(err) == 1, err
    assert "penetration<0.05 broken at frame 1 by /World/Hair" in err[0]
    assert float(err[0].rsplit("= ", 1)[1]) >= (R_HAIR + 0.04) / R_HAIR * (1 - 1e-5)   # float32
    assert not out.exists()
    # without the gate: every frame, as the roots hold it inside; a prim without widths is noted
    summary = simulate_usd(tmp_path / "in.usda", out, device="cpu", solver="dftl")
    assert any(w.startswith("/World/Bare: no hair widths") for w in summary.warnings), summary.warnings
    written = Usd.Stage.Open(str(out))
    for prim, low in (("World_Hair", (R_HAIR + 0.04) / R_HAIR * (1 - 1e-5)), ("World_Fur", 0.0), ("World_Bare", 0.0)):
        qc = written.GetPrimAtPath(f"/dftl_qc/{prim}").GetAttribute(ATTRIBUTES["penetration"])
        values = [qc.Get(t) for t in qc.GetTimeSamples()]
        assert len(values) == 4 and min(values) >= low and (low > 0 or max(values) == 0.0), (prim, values)
    (tmp_path / "jobs.toml").write_text('[[job]]\ninput = "in.usda"\noutput = "o.usdc"\ncheck = "penetration<0.05"\n'
                                        'solver = "dftl"\n')
    result = run_job(load_jobs(tmp_path / "jobs.toml")[0], "cpu")
    assert result.status == "failed" and "penetration<0.05 broken at frame 1 by /World/Hair" in result.error


def test_penetration_is_one_more_launch_per_frame(monkeypatch):
    """On the default scene (3000 strands x 16, a sphere collider): the QC of a frame launches the
    QC kernel and the penetration kernel, nothing else (their cost: scripts/bench_qc.py)."""
    from pathlib import Path

    import warp as wp

    from dftl_warp.output.qc import FrameQC
    from dftl_warp.simulation.simulate import Simulation, SimulationOptions
    from dftl_warp.usd.read import read_scene

    scene = read_scene(str(Path(__file__).resolve().parent.parent / "scenes" / "default.usda"))
    sim = Simulation(scene, SimulationOptions(device="cpu", solver="dftl"), 1)
    qc = FrameQC(sim)
    sim.advance(), sim.samples()
    launched = []
    launch = wp.launch
    monkeypatch.setattr(wp, "launch", lambda kernel, *a, **k: (launched.append(kernel.key), launch(kernel, *a, **k)))
    assert qc.compute()["/World/Head/Hair"]["penetration"] < 0.01   # the collider keeps it out
    assert [k.split("_locals__")[-1] for k in launched] == ["prim_qc", "prim_penetration"], launched


def test_split_over_two_devices_measures_bitwise_the_same(tmp_path):
    """Six strands rooted at various depths in a sphere (R = 10 cm), split over two CPU devices or
    not: the same QC bit for bit, every frame. The deepest particle is the one next to the deepest
    root, pushed out as far as its 1 cm rest length lets it: (r + R - |root| - 1 cm) / r."""
    from dftl_warp.output.qc import FrameQC
    from dftl_warp.simulation.simulate import Simulation, SimulationOptions
    from dftl_warp.usd.read import read_scene

    stage = new_stage(tmp_path / "in.usda", start=1, end=4)
    roots = np.array([(0.02 * k, 0.05 - 0.005 * k, 0.0) for k in range(6)])
    strands = [chain(12, 0.01, direction=(0.0, 1.0, 0.0), origin=r) for r in roots]
    add_curves(stage, "/World/Hair", np.concatenate(strands), [12] * 6, widths=2 * R_HAIR)
    sphere(stage, "/World/Ball", 0.1)
    stage.Save()
    runs = {}
    for devices in ("cpu", "cpu,cpu"):
        sim = Simulation(read_scene(str(tmp_path / "in.usda")), SimulationOptions(device=devices, solver="dftl"), 1)
        qc = FrameQC(sim)
        values = [qc.compute()["/World/Hair"]["penetration"]]
        for _ in range(3):
            sim.advance(), sim.samples()
            values.append(qc.compute()["/World/Hair"]["penetration"])
        runs[devices] = values
    assert runs["cpu"] == runs["cpu,cpu"]
    deepest = (R_HAIR + 0.1 - np.linalg.norm(roots, axis=1).min() - 0.01) / R_HAIR
    assert runs["cpu"] == pytest.approx([deepest] * 4, rel=1e-5)
