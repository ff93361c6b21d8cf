"""``--clips`` on grooms whose frames are smaller than a memory page (docs/caches.md, "Value
clips"): the shared frame memory is rounded up to a page, and the writer processes must use only
its slots, not the whole mapping. The clips compose to the points of a plain run."""

from pathlib import Path

import numpy as np
import pytest
from pxr import Usd, UsdGeom
from usd_stages import add_curves, chain, new_stage

from dftl_warp import cli
from dftl_warp.output.clip_pool import ClipWriterPool

ROOT = Path(__file__).resolve().parent.parent


def samples(path):
    """{(prim, attribute): {time: array}} of every PointBased prim's points, velocities, extent."""
    stage = Usd.Stage.Open(str(path))
    out = {}
    for prim in stage.Traverse():
        if prim.IsA(UsdGeom.PointBased):
            for name in ("points", "velocities", "extent"):
                attr = prim.GetAttribute(name)
                out[str(prim.GetPath()), name] = {t: np.asarray(attr.Get(t)) for t in attr.GetTimeSamples()}
    return out


def tiny(path):
    """2 strands of 4 particles (8 in all: one frame is 96 bytes, 192 with velocities)."""
    stage = new_stage(path, end=10)
    pts = np.concatenate([chain(4, 0.05, origin=(0.0, 1.0, 0.1 * s)) for s in range(2)])
    add_curves(stage, "/World/Hair", pts, [4, 4])
    stage.Save()
    return path


@pytest.mark.parametrize("scene,end", [("chain", 6), ("tiny", 7)])
def test_clips_of_a_small_groom_equal_a_plain_run(tmp_path, capfd, scene, end):
    src = ROOT / "scenes" / "chain.usda" if scene == "chain" else tiny(tmp_path / "in.usda")
    base = ["--end", str(end), "--quiet", "--device", "cpu"]
    assert cli.main(["simulate", str(src), "-o", str(tmp_path / "plain.usdc"), *base]) == 0
    assert cli.main(["simulate", str(src), "-o", str(tmp_path / "clips.usdc"), "--clips", "2", *base]) == 0
    err = capfd.readouterr().err
    assert "Traceback" not in err and "error" not in err
    assert sorted(p.name for p in (tmp_path / "clips_clips").iterdir()) == \
        [f"clip.{k:04d}.usdc" for k in range((end + 1) // 2)] + ["topology.usdc"]
    plain, clips = samples(tmp_path / "plain.usdc"), samples(tmp_path / "clips.usdc")
    assert plain.keys() == clips.keys() and plain
    for key, frames in plain.items():
        assert sorted(frames) == sorted(clips[key]) == [float(t) for t in range(1, end + 1)], key
        for t, value in frames.items():
            assert np.array_equal(value, clips[key][t]), (key, t)


def test_a_pool_whose_slots_fill_less_than_a_page_authors_every_frame(tmp_path):
    """Direct: 5 points a frame, slots not dividing the page; every sample reaches its layer."""
    rng = np.random.default_rng(1)
    pool = ClipWriterPool([("/World/Hair", None)], [5], velocities=True, writers=2, name=str(tmp_path))
    try:
        assert 4 * pool.frames.size < 4096  # the case the writers used to fail on
        frames = {t: (rng.random((5, 3), np.float32), rng.random((5, 3), np.float32)) for t in range(1, 7)}
        for t, (p, v) in frames.items():
            chunk = (t - 1) // 3
            pool.put_frame(chunk, tmp_path / f"clip.{chunk}.usdc", float(t), [(p, v)])
            if t % 3 == 0:
                pool.save(chunk)
        assert pool.result(0) is None and pool.result(1) is None
    finally:
        pool.close()
    for chunk in (0, 1):
        stage = Usd.Stage.Open(str(tmp_path / f"clip.{chunk}.usdc"))
        prim = stage.GetPrimAtPath("/World/Hair")
        for t in range(3 * chunk + 1, 3 * chunk + 4):
            assert np.array_equal(np.asarray(prim.GetAttribute("points").Get(t)), frames[t][0])
            assert np.array_equal(np.asarray(prim.GetAttribute("velocities").Get(t)), frames[t][1])
