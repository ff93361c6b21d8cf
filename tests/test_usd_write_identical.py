"""The writer's fast numpy -> Vt conversion (dftl_warp/output/vtarrays.py) writes exactly what
``Vt.Vec3fArray.FromBuffer`` (the writer's conversion before it) writes: array by array, bit for bit,
and as a whole output of a simulated scene with several prims, velocities, widths and an elastic prim."""

from __future__ import annotations

import numpy as np
import pytest
from pxr import Sdf, Usd, UsdGeom, Vt
from usd_stages import add_curves, chain, new_stage

from dftl_warp.output import vtarrays
from dftl_warp.output.usd import UsdWriter
from dftl_warp.output.vtarrays import vec3f_array
from dftl_warp.simulation.simulate import Simulation, SimulationOptions
from dftl_warp.usd.read import read_scene


def bits(array) -> np.ndarray:
    """The float32 bit patterns of a Vt.Vec3fArray (NaN compares by its bits too)."""
    return np.array(array, dtype=np.float32).reshape(-1, 3).view(np.uint32)


def reference(rows) -> Vt.Vec3fArray:
    """The writer's conversion before vtarrays: Vt's FromBuffer of an (N, 3) contiguous float array."""
    a = np.asarray(rows)
    if a.dtype not in (np.float32, np.float64):
        a = a.astype(np.float64)
    return Vt.Vec3fArray.FromBuffer(np.ascontiguousarray(a).reshape(-1, 3))


def awkward_rows() -> np.ndarray:
    """float64 rows that round when made float32, out of float32's range, NaN, inf, subnormal, -0."""
    rng = np.random.default_rng(3)
    a = rng.normal(size=(40, 3)) * 10.0 ** rng.integers(-8, 8, size=(40, 1))
    a[0] = (1e300, -1e300, np.nan)
    a[1] = (np.inf, -np.inf, -0.0)
    a[2] = (1e-42, -1e-45, 3.4028235677973366e38)   # subnormals; just above float32's largest
    a[3] = (0.1, 1.0 / 3.0, 2.0 ** -149 * 0.5)
    return a


def test_the_storage_is_filled_in_place_on_this_usd_core():
    """Else every other test here would compare FromBuffer with itself."""
    assert vtarrays._fill_shows()
    vec3f_array(np.zeros((1, 3), np.float32))
    assert vtarrays._in_place is True


@pytest.mark.parametrize("make", [
    lambda a: a,                                     # float64 (N, 3)
    lambda a: np.clip(a, -1e38, 1e38).astype(np.float32),   # float32, as the simulator hands them over
    lambda a: a.reshape(-1),                         # flat 3N
    lambda a: a[::2],                                # a strided view
    lambda a: np.asfortranarray(a),                  # column-major
    lambda a: a[:0],                                 # no points
    lambda a: np.nan_to_num(np.clip(a, -1e9, 1e9), nan=0.0).astype(np.int64),   # integers
], ids=["float64", "float32", "flat", "strided", "fortran", "empty", "int64"])
def test_conversion_is_bitwise_frombuffer(make):
    rows = make(awkward_rows())
    fast, ref = vec3f_array(rows), reference(rows)
    assert isinstance(fast, Vt.Vec3fArray) and len(fast) == len(ref)
    np.testing.assert_array_equal(bits(fast), bits(ref))


def test_conversion_makes_a_new_array_each_call():
    rows = np.ones((5, 3), np.float32)
    a = vec3f_array(rows)
    rows += 1.0
    b = vec3f_array(rows)
    assert np.all(np.array(a) == 1.0) and np.all(np.array(b) == 2.0)


def test_fallback_when_the_storage_is_not_exported(monkeypatch):
    monkeypatch.setattr(vtarrays, "_in_place", False)
    rows = awkward_rows()
    np.testing.assert_array_equal(bits(vec3f_array(rows)), bits(reference(rows)))


def scene_file(path):
    """Three prims under a moved Xform: DFTL without widths, DFTL with constant widths, and an elastic
    prim (per-vertex widths, bending left to its default)."""
    stage = new_stage(path, start=1, end=4)
    UsdGeom.Xform.Define(stage, "/World/Groom").AddTranslateOp().Set((0.3, 1.0, -0.2))
    plain = np.concatenate([chain(5, 0.02, direction=(0, -1, 0), origin=(0.05 * s, 0, 0)) for s in range(3)])
    add_curves(stage, "/World/Groom/Plain", plain, [5] * 3)
    thick = np.concatenate([chain(4, 0.03, direction=(0, -1, 0.2), origin=(0, 0, 0.04 * s)) for s in range(2)])
    add_curves(stage, "/World/Groom/Thick", thick, [4] * 2, widths=0.002)
    rod = chain(6, 0.02, direction=(1, -1, 0))
    elastic = add_curves(stage, "/World/Groom/Rod", rod, [6], widths=np.linspace(0.003, 0.001, 6), bending=None)
    elastic.GetPrim().CreateAttribute("dftl:solver", Sdf.ValueTypeNames.Token).Set("elastic")
    stage.Save()
    return path


def write(out, scene, frames, monkeypatch, *, fast: bool, float64: bool):
    monkeypatch.setattr(vtarrays, "_in_place", None if fast else False)
    writer = UsdWriter.create(out, scene, frames=(1, len(frames)))
    for time, samples in enumerate(frames, start=1):
        if float64:
            samples = [(p.astype(np.float64), v.astype(np.float64)) for p, v in samples]
        writer.write_frame(time, samples)
    writer.commit()
    return out


def all_samples(path) -> dict:
    """{(prim, attribute): {time: bits}} of every time-sampled attribute of the composed stage."""
    stage = Usd.Stage.Open(str(path))
    out = {}
    for prim in stage.Traverse():
        for attr in prim.GetAttributes():
            times = attr.GetTimeSamples()
            if times:
                out[(str(prim.GetPath()), attr.GetName())] = {
                    t: np.array(attr.Get(t), dtype=np.float32).view(np.uint32).tobytes() for t in times}
    return out


@pytest.mark.parametrize("float64", [False, True], ids=["float32-in", "float64-in"])
def test_simulated_output_is_identical_to_the_frombuffer_writer(tmp_path, monkeypatch, float64):
    src = scene_file(tmp_path / "in.usda")
    scene = read_scene(src)
    sim = Simulation(scene, SimulationOptions(start=1, end=4), 1)
    assert sorted(g.settings.solver for g in sim.groups) == ["dftl", "elastic"]
    frames = [sim.samples()]
    for _ in range(3):
        sim.advance()
        frames.append(sim.samples())
    fast = write(tmp_path / "fast.usda", scene, frames, monkeypatch, fast=True, float64=float64)
    ref = write(tmp_path / "ref.usda", scene, frames, monkeypatch, fast=False, float64=float64)
    assert fast.read_text() == ref.read_text()
    got, want = all_samples(fast), all_samples(ref)
    assert set(want) == {(f"/World/Groom/{p}", a) for p in ("Plain", "Thick", "Rod")
                         for a in ("points", "velocities", "extent")}
    assert got == want
    assert all(sorted(t) == [1.0, 2.0, 3.0, 4.0] for t in got.values())
    layer = Sdf.Layer.FindOrOpen(str(fast))
    assert layer.GetAttributeAtPath("/World/Groom/Rod.points").GetInfo("typeName") == "point3f[]"


def test_a_clip_writer_chunk_is_identical_to_the_frombuffer_one(tmp_path, monkeypatch):
    """The value-clips writer process's chunk layer (output/clip_process.py), authored in this process."""
    from dftl_warp.output.clip_process import _Chunk

    rng = np.random.default_rng(5)
    targets = [("/World/A", None), ("/World/B", np.linspace(0.004, 0.001, 12))]
    widths = [None if w is None else Vt.FloatArray.FromNumpy(w.astype(np.float32)) for _, w in targets]
    frames = [[(rng.normal(size=(n, 3)).astype(np.float32), rng.normal(size=(n, 3)).astype(np.float32) if v else None)
               for n, v in ((7, True), (12, False))] for _ in range(3)]
    texts = []
    for fast in (True, False):
        monkeypatch.setattr(vtarrays, "_in_place", None if fast else False)
        chunk = _Chunk(str(tmp_path / f"clip.{fast}.usdc"), targets, True)
        for time, arrays in enumerate(frames):
            chunk.add(float(time), arrays, widths)
        texts.append(chunk.layer.ExportToString())
        chunk.drop()
    assert texts[0] == texts[1]
    assert texts[0].count("points.timeSamples") == 2 and texts[0].count("velocities.timeSamples") == 1
