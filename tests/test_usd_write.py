"""Writing rules: layer structure, metadata, samples, streaming memory, atomic output, resume,
and UsdValidation."""

from pathlib import Path

import numpy as np
import pytest
from pxr import Sdf, Usd, UsdGeom, UsdValidation
from usd_stages import add_curves, chain, composed_samples, new_stage

from dftl_warp.simulation.simulate import Simulation, SimulationOptions, run_frames, simulate_usd
from dftl_warp.usd.read import read_scene
from dftl_warp.output.usd import UsdWriter, partial_path

ROOT = Path(__file__).resolve().parent.parent


def groom_file(path, strands=4, vertices=5, *, widths=None, **stage_kw):
    stage = new_stage(path, **stage_kw)
    pts = np.concatenate([chain(vertices, 0.1, origin=(0.0, 0.0, 0.2 * s)) for s in range(strands)])
    add_curves(stage, "/World/Hair", pts, [vertices] * strands, widths=widths)
    UsdGeom.Sphere.Define(stage, "/World/Head")
    stage.Save()
    return Path(path)


def test_output_layer_structure_and_metadata(tmp_path):
    (tmp_path / "scenes").mkdir()
    (tmp_path / "out").mkdir()
    src = groom_file(tmp_path / "scenes" / "in.usda", up="Z", meters_per_unit=0.01, start=2, end=6, fps=30.0,
                     widths=0.1)
    out = tmp_path / "out" / "sim.usdc"
    summary = simulate_usd(src, out)
    assert (summary.frames, summary.first_frame, summary.last_frame) == (5, 2, 6)

    layer = Sdf.Layer.FindOrOpen(str(out))
    assert list(layer.subLayerPaths) == ["../scenes/in.usda"]
    assert layer.GetPrimAtPath("/World").specifier == Sdf.SpecifierOver
    hair = layer.GetPrimAtPath("/World/Hair")
    assert hair.specifier == Sdf.SpecifierOver
    assert sorted(hair.attributes.keys()) == ["extent", "points", "velocities"]
    assert layer.GetPrimAtPath("/World/Head") is None  # only simulated prims get overs
    for name in ("points", "velocities", "extent"):
        assert layer.ListTimeSamplesForPath(f"/World/Hair.{name}") == [2.0, 3.0, 4.0, 5.0, 6.0]
    root = layer.pseudoRoot
    assert (root.GetInfo("upAxis"), root.GetInfo("metersPerUnit")) == ("Z", 0.01)
    assert (layer.timeCodesPerSecond, layer.startTimeCode, layer.endTimeCode, layer.defaultPrim) == (30.0, 2.0, 6.0, "World")

    # opening the output shows the whole scene, animated
    stage = Usd.Stage.Open(str(out))
    assert stage.GetPrimAtPath("/World/Head").IsA(UsdGeom.Sphere)
    curves = UsdGeom.BasisCurves(stage.GetPrimAtPath("/World/Hair"))
    first = np.array(curves.GetPointsAttr().Get(2.0))
    source = Usd.Stage.Open(str(src))
    np.testing.assert_allclose(first, np.array(source.GetPrimAtPath("/World/Hair").GetAttribute("points").Get()))
    np.testing.assert_array_equal(np.array(curves.GetVelocitiesAttr().Get(2.0)), 0.0)
    for t in (2.0, 4.0, 6.0):
        p = np.array(curves.GetPointsAttr().Get(t))
        ext = np.array(curves.GetExtentAttr().Get(t))
        np.testing.assert_allclose(ext, [p.min(axis=0) - 0.05, p.max(axis=0) + 0.05], rtol=1e-6, atol=1e-6)
    assert np.array(curves.GetPointsAttr().Get(6.0))[:, 2].min() < first[:, 2].min() - 0.2  # fell along -Z


def test_same_folder_sublayer_and_effective_metadata_for_unauthored_fields(tmp_path):
    src = groom_file(tmp_path / "in.usda", up=None, meters_per_unit=None, fps=None, default_prim=False)
    simulate_usd(src, tmp_path / "o.usdc", end=3)
    layer = Sdf.Layer.FindOrOpen(str(tmp_path / "o.usdc"))
    assert list(layer.subLayerPaths) == ["./in.usda"]
    assert (layer.pseudoRoot.GetInfo("upAxis"), layer.pseudoRoot.GetInfo("metersPerUnit")) == ("Y", 0.01)
    assert layer.timeCodesPerSecond == 24.0 and not layer.HasDefaultPrim()


def test_usda_output_holds_the_same_samples_as_usdc(tmp_path):
    src = groom_file(tmp_path / "in.usda")
    simulate_usd(src, tmp_path / "a.usdc", end=4)
    simulate_usd(src, tmp_path / "a.usda", end=4)
    assert (tmp_path / "a.usda").read_text().startswith("#usda 1.0")
    for attr in ("points", "velocities", "extent"):
        c = composed_samples(tmp_path / "a.usdc", "/World/Hair", attr)
        a = composed_samples(tmp_path / "a.usda", "/World/Hair", attr)
        assert sorted(c) == sorted(a) == [1.0, 2.0, 3.0, 4.0]
        for t in c:
            np.testing.assert_array_equal(c[t], a[t])
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.usda", "a.usdc", "in.usda"]


def _rss_mib():
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * 4096 / 2**20


def _release_free_heap():
    """Hand the heap's free pages back to the OS (glibc malloc_trim), so that memory freed by
    earlier tests cannot absorb this test's growth without showing in the resident size."""
    import ctypes
    import gc

    gc.collect()
    try:
        ctypes.CDLL("libc.so.6").malloc_trim(0)
    except (OSError, AttributeError):
        pass


@pytest.mark.parametrize("streaming", [True, False])
def test_memory_stays_flat_while_streaming(tmp_path, streaming):
    """100k points per frame, 80 frames (190 MiB of samples). Saving every 8 MiB keeps the
    process's resident memory flat; the control run, never saving until the end, grows by the
    size of the samples -- which shows the measurement can see growth."""
    strands, vertices, frames = 6250, 16, 80
    src = groom_file(tmp_path / "in.usdc", strands=strands, vertices=vertices)
    scene = read_scene(src)
    rng = np.random.default_rng(0)
    points = rng.standard_normal((strands * vertices, 3))
    velocities = rng.standard_normal((strands * vertices, 3))
    flush = 8 << 20 if streaming else 1 << 40
    writer = UsdWriter.create(tmp_path / "big.usdc", scene, flush_bytes=flush)
    rss = []
    for f in range(frames):
        writer.write_frame(f, [(points + f, velocities)])
        if f == 10:
            _release_free_heap()
        if f in (10, frames - 1):
            rss.append(_rss_mib())
    growth = rss[1] - rss[0]
    writer.commit()
    sample_mib = 24 * strands * vertices * (frames - 11) / 2**20
    if streaming:
        assert growth < 0.25 * sample_mib, (growth, sample_mib)
    else:
        assert growth > 0.75 * sample_mib, (growth, sample_mib)
    assert Usd.Stage.Open(str(tmp_path / "big.usdc")).GetPrimAtPath("/World/Hair").GetAttribute(
        "points").GetNumTimeSamples() == frames


def test_resume_from_saved_state_and_partial_output_matches_one_run(tmp_path):
    """The batch/resume design: simulate frames 1..5, keep the partial file and the solver state,
    continue in a new Simulation and reopened writer to frame 10; same result as one run."""
    src = groom_file(tmp_path / "in.usda")
    stage = Usd.Stage.Open(str(src))
    UsdGeom.Xform(stage.GetPrimAtPath("/World")).AddTranslateOp().Set((0.0, 0.0, 0.0), 1)
    UsdGeom.Xform(stage.GetPrimAtPath("/World")).GetOrderedXformOps()[0].Set((0.5, 0.0, 0.0), 10)
    stage.Save()
    simulate_usd(src, tmp_path / "once.usdc")

    out = tmp_path / "twice.usdc"
    options = SimulationOptions()
    scene = read_scene(src)
    sim = Simulation(scene, options, 1)
    writer = UsdWriter.create(out, scene, frames=(1, 10), keep_partial=True)
    run_frames(sim, writer, 5)
    writer.flush()
    saved = sim.save_state()
    writer.abort()  # e.g. the machine went away: the partial file stays
    assert partial_path(out).exists() and not out.exists()

    scene = read_scene(src)
    sim = Simulation(scene, options, 1)
    sim.load_state(saved)
    writer = UsdWriter.reopen(out, scene)
    assert writer.last_time_code == 5.0 == sim.frame
    run_frames(sim, writer, 10, write_first=False)
    writer.commit()
    assert not partial_path(out).exists()
    for attr in ("points", "velocities", "extent"):
        once = composed_samples(tmp_path / "once.usdc", "/World/Hair", attr)
        twice = composed_samples(out, "/World/Hair", attr)
        assert sorted(once) == sorted(twice) == [float(f) for f in range(1, 11)]
        for t in once:
            np.testing.assert_array_equal(once[t], twice[t])


def _errors(path):
    ctx = UsdValidation.ValidationContext(UsdValidation.ValidationRegistry().GetOrLoadAllValidators())
    out = set()
    for e in ctx.Validate(Usd.Stage.Open(str(path))):
        if e.GetType() in (UsdValidation.ValidationErrorType.Error, UsdValidation.ValidationErrorType.Warn):
            sites = tuple(sorted(str(s.GetPrim().GetPath()) for s in e.GetSites() if s.IsPrim()))
            out.add((e.GetValidator().GetMetadata().name if e.GetValidator() else "", e.GetName(), sites))
    return out


def test_output_passes_every_registered_validator_for_the_default_scene(tmp_path):
    assert len(UsdValidation.ValidationRegistry().GetOrLoadAllValidators()) > 10
    out = tmp_path / "demo.usdc"
    simulate_usd(ROOT / "scenes" / "default.usda", out, end=3)
    assert _errors(ROOT / "scenes" / "default.usda") == set()
    assert _errors(out) == set()


def test_usdz_input_output_validates(tmp_path):
    from pxr import UsdUtils

    src = groom_file(tmp_path / "in.usda")
    assert UsdUtils.CreateNewUsdzPackage(Sdf.AssetPath(str(src)), str(tmp_path / "in.usdz"))
    simulate_usd(tmp_path / "in.usdz", tmp_path / "o.usdc", end=3)
    assert list(Sdf.Layer.FindOrOpen(str(tmp_path / "o.usdc")).subLayerPaths) == ["./in.usdz"]
    assert _errors(tmp_path / "in.usdz") == _errors(tmp_path / "o.usdc") == set()
    assert len(composed_samples(tmp_path / "o.usdc", "/World/Hair")) == 3


def test_output_adds_no_validation_errors_to_a_flawed_input(tmp_path):
    src = groom_file(tmp_path / "in.usda", up=None, meters_per_unit=None, default_prim=False)
    before = _errors(src)
    assert {name for _, name, _ in before} >= {"MissingDefaultPrim", "MissingMetersPerUnitMetadata"}
    simulate_usd(src, tmp_path / "o.usda", end=3)
    after = _errors(tmp_path / "o.usda")
    assert after <= before, after - before


def test_written_frames_are_each_frames_own_samples(tmp_path):
    """run_frames writes straight from the host buffers (no copy); each frame must still be its own."""
    src = groom_file(tmp_path / "in.usda")
    out = tmp_path / "out.usdc"
    simulate_usd(src, out, start=1, end=6)
    sim = Simulation(read_scene(src), SimulationOptions(start=1, end=6), 1)
    stage = Usd.Stage.Open(str(out))
    curves = UsdGeom.BasisCurves(stage.GetPrimAtPath("/World/Hair"))
    previous = None
    for frame in range(1, 7):
        if frame > 1:
            sim.advance()
        (points, velocities), = sim.samples()
        assert np.array_equal(np.array(curves.GetPointsAttr().Get(frame)), points), frame
        assert np.array_equal(np.array(curves.GetVelocitiesAttr().Get(frame)), velocities), frame
        assert previous is None or not np.array_equal(previous, points)
        previous = points
