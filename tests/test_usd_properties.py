"""Property tests: random (often malformed) curve data thrown at the loader.

Whatever the data, the loader either refuses it with a one-line UserError naming the file and the
prim, or returns strands the simulator accepts and simulates to finite positions.
"""

import numpy as np
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st
from pxr import Usd, UsdGeom, Vt

from dftl_warp.errors import UserError
from dftl_warp.simulation.simulate import Simulation, SimulationOptions
from dftl_warp.usd.read import read_scene

FAULTS = ["none", "none", "none", "zero count", "negative count", "extra point", "missing point", "nan",
          "inf", "huge", "periodic", "bad type", "bad basis", "bad wrap", "no points", "no counts", "duplicate points"]


@st.composite
def curve_data(draw):
    """Valid curves with, often, one or more faults injected."""
    counts = draw(st.lists(st.integers(min_value=1, max_value=6), min_size=1, max_size=6))
    n = sum(counts)
    flat = draw(st.lists(st.floats(min_value=-1e3, max_value=1e3, allow_nan=False, width=32),
                         min_size=3 * n, max_size=3 * n))
    data = {
        "counts": counts,
        "points": np.array(flat, dtype=np.float32).reshape(n, 3),
        "type": draw(st.sampled_from(["linear", "cubic"])),
        "basis": draw(st.sampled_from(["bezier", "bspline", "catmullRom"])),
        "wrap": draw(st.sampled_from(["nonperiodic", "pinned"])),
        "author_points": True,
    }
    for fault in draw(st.lists(st.sampled_from(FAULTS), min_size=1, max_size=3)):
        i = draw(st.integers(min_value=0, max_value=10**6))
        pts = data["points"]
        if fault == "zero count" and data["counts"]:
            data["counts"][i % len(data["counts"])] = 0
        elif fault == "negative count" and data["counts"]:
            data["counts"][i % len(data["counts"])] = -1 - i % 3
        elif fault == "extra point":
            data["points"] = np.concatenate([pts, np.ones((1 + i % 2, 3), np.float32)])
        elif fault == "missing point" and len(pts):
            data["points"] = pts[:-1]
        elif fault in ("nan", "inf", "huge") and len(pts):
            pts[i % len(pts), i % 3] = {"nan": np.nan, "inf": np.inf * (-1) ** i, "huge": 3e38 * (-1) ** i}[fault]
        elif fault == "periodic":
            data["wrap"] = "periodic"
        elif fault == "bad type":
            data["type"] = "spline"
        elif fault == "bad basis":
            data["basis"] = "hermite"
        elif fault == "bad wrap":
            data["wrap"] = "loop"
        elif fault == "no points":
            data["author_points"] = False
        elif fault == "no counts":
            data["counts"] = []
        elif fault == "duplicate points" and len(pts) > 1:
            pts[1:] = pts[:-1].copy()  # zero-length segments everywhere after the first
    return data


def stage_with(data):
    stage = Usd.Stage.CreateInMemory("fuzz.usda")
    stage.SetStartTimeCode(1)
    stage.SetEndTimeCode(2)
    curves = UsdGeom.BasisCurves.Define(stage, "/World/Hair")
    curves.CreateTypeAttr(data["type"])
    curves.CreateBasisAttr(data["basis"])
    curves.CreateWrapAttr(data["wrap"])
    curves.CreateCurveVertexCountsAttr(Vt.IntArray(data["counts"]))
    if data["author_points"]:
        curves.CreatePointsAttr(Vt.Vec3fArray.FromNumpy(np.ascontiguousarray(data["points"])))
    return stage


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(curve_data())
def test_loader_refuses_cleanly_or_returns_simulatable_strands(data):
    stage = stage_with(data)
    file = stage.GetRootLayer().identifier
    try:
        scene = read_scene(stage)
    except UserError as err:
        message = str(err)
        assert "\n" not in message
        assert message.startswith(f"{file}: ")
        assert "/World/Hair" in message or "no curves to simulate" in message
        event("refused by the loader")
        return
    (curves,) = scene.curves
    assert curves.wrap in ("nonperiodic", "pinned") and curves.type in ("linear", "cubic")
    assert curves.counts.min() >= 1 and curves.counts.sum() == curves.points.shape[0]
    assert np.isfinite(curves.points).all()
    try:
        sim = Simulation(scene, SimulationOptions(substeps=2), 1)
    except UserError as err:  # e.g. points too far apart for float32
        assert str(err).startswith(f"{file}: /World/Hair: points[")
        event("refused by the simulation (too far apart)")
        return
    sim.advance()
    (points, velocities), = sim.samples()
    assert np.isfinite(points).all() and np.isfinite(velocities).all()
    np.testing.assert_array_equal(points[curves.root_indices], curves.points[curves.root_indices])
    event("simulated")
