#!/usr/bin/env python3
"""Check that a frame replayed from a CUDA graph equals the same frame launched kernel by kernel.

On CUDA each frame's substeps are captured once into a graph and replayed
(``Solver.launch_frame``, dftl_warp/solvers/base.py); a graph replays the host scalars it was
captured with, so a scalar that changes between frames and is missing from the graph's key would
replay a stale value (a preroll's clamp mode did, fixed in b116894). This runs one time-varying
scene twice through ``simulate_usd`` -- with graphs, and with ``launch_frame`` calling the frame
directly -- and compares the written points bit for bit (docs/gpu-checks.md).

The scene (10 frames at 24 fps): a head turning 50 degrees and moving 5 cm carrying the roots and a
3 cm ball, a deforming 8 cm box (its points move 2 cm a frame; once with exact mesh queries, once
through its signed distance field), wind gusting from 0 to 3 m/s with drag 1/s, seven 22 cm DFTL
strands and five elastic curls of 100 um hair; a third run settles the groom for 0.1 s first
(``--preroll``: its graphs are captured with the clamps relative to the roots). No hair-hair: its atomics add in any order, so two
runs differ in the last bits whatever launches them.

    python scripts/check_graph_replay.py --device cuda:0 --out /tmp/replay

Exit status 1 if any written point differs. On the CPU (no graphs) both runs are the same launches.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
from pxr import Gf, Sdf, Usd, UsdGeom, UsdPhysics, Vt

import dftl_warp.solvers.base as base
from dftl_warp.simulation.simulate import simulate_usd

PRIMS = ("/World/Head/Straight", "/World/Head/Curls")


def _attr(prim, name, type_name, value, time=None):
    a = prim.CreateAttribute(name, getattr(Sdf.ValueTypeNames, type_name), custom=True)
    a.Set(value) if time is None else a.Set(value, time)


def _curves(stage, path, strands, width, bending):
    c = UsdGeom.BasisCurves.Define(stage, path)
    c.CreateTypeAttr("linear")
    c.CreateCurveVertexCountsAttr(Vt.IntArray([len(s) for s in strands]))
    c.CreatePointsAttr(Vt.Vec3fArray.FromNumpy(np.concatenate(strands).astype(np.float32)))
    c.CreateWidthsAttr(Vt.FloatArray([width]))
    c.SetWidthsInterpolation("constant")
    if not bending:
        _attr(c.GetPrim(), "dftl:bending", "Bool", False)
    _attr(c.GetPrim(), "dftl:drag", "Float", 1.0)


def write_stage(path: str, sdf: bool) -> None:
    """The scene of the module docstring (metres, Y up)."""
    stage = Usd.Stage.CreateNew(path)
    UsdGeom.SetStageUpAxis(stage, "Y")
    UsdGeom.SetStageMetersPerUnit(stage, 1.0)
    stage.SetStartTimeCode(1)
    stage.SetEndTimeCode(10)
    world = UsdGeom.Xform.Define(stage, "/World").GetPrim()
    stage.SetDefaultPrim(world)
    for frame, w in ((1, (0.0, 0.0, 0.0)), (4, (3.0, 0.0, 1.0)), (7, (-2.0, 0.5, 0.0)), (10, (0.0, 0.0, -3.0))):
        _attr(world, "dftl:wind", "Float3", Gf.Vec3f(*w), frame)
    head = UsdGeom.Xform.Define(stage, "/World/Head")
    move, turn = head.AddTranslateOp(), head.AddRotateYOp()
    for frame, (x, y, angle) in ((1, (0.0, 0.0, 0.0)), (10, (0.05, 0.02, 50.0))):
        move.Set(Gf.Vec3d(x, y, 0.0), frame)
        turn.Set(angle, frame)
    ball = UsdGeom.Sphere.Define(stage, "/World/Head/Ball")
    ball.CreateRadiusAttr(0.03)
    ball.AddTranslateOp().Set(Gf.Vec3d(0.0, -0.12, 0.0))
    UsdPhysics.CollisionAPI.Apply(ball.GetPrim())
    corners = np.array([[x, y, z] for x in (-0.04, 0.04) for y in (-0.04, 0.04) for z in (-0.04, 0.04)])
    quads = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    body = UsdGeom.Mesh.Define(stage, "/World/Body")
    body.CreateFaceVertexCountsAttr(Vt.IntArray([3] * 12))
    body.CreateFaceVertexIndicesAttr(Vt.IntArray([i for a, b, c, d in quads for i in (a, b, c, a, c, d)]))
    for frame in range(1, 11):
        at = (corners + [-0.15 + 0.02 * frame, -0.25, 0.0]).astype(np.float32)
        body.GetPointsAttr().Set(Vt.Vec3fArray.FromNumpy(at), frame)
    UsdPhysics.CollisionAPI.Apply(body.GetPrim())
    if sdf:
        _attr(body.GetPrim(), "dftl:collisionSdf", "Bool", True)
    i = np.arange(12)[:, None]
    straight = [np.array([0.02 * k - 0.06, 0.0, 0.01 * k]) + 0.02 * i * np.array([0.1 * k, -1.0, 0.05])
                for k in range(7)]
    _curves(stage, "/World/Head/Straight", straight, 2e-4, bending=False)
    t = np.linspace(0.0, 4 * np.pi, 14)
    curls = [np.c_[0.006 * np.cos(t) + 0.02 * k - 0.05, -0.012 * np.arange(14), 0.006 * np.sin(t) + 0.03]
             for k in range(5)]
    _curves(stage, "/World/Head/Curls", curls, 1e-4, bending=True)
    stage.GetRootLayer().Save()


def _points(path: str) -> dict:
    stage = Usd.Stage.Open(path)
    out = {}
    for prim in PRIMS:
        a = stage.GetPrimAtPath(prim).GetAttribute("points")
        out[prim] = {t: np.array(a.Get(t), dtype=np.float64) for t in a.GetTimeSamples()}
    return out


def _direct(self, state, control, dt, substeps, run, kernels, variant=()):
    run()


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--device", default="cuda:0")
    ap.add_argument("--out", required=True, help="folder for the stages and caches")
    args = ap.parse_args(argv)
    Path(args.out).mkdir(parents=True, exist_ok=True)
    differs = False
    for sdf, preroll in ((False, 0.0), (True, 0.0), (False, 0.1)):
        name = f"{args.out}/replay-sdf-{sdf}-preroll-{preroll}"
        write_stage(f"{name}.usda", sdf)
        written = {}
        for mode in ("graph", "direct"):
            keep = base.Solver.launch_frame
            if mode == "direct":
                base.Solver.launch_frame = _direct
            try:
                simulate_usd(f"{name}.usda", f"{name}-{mode}.usdc", device=args.device, preroll=preroll)
            finally:
                base.Solver.launch_frame = keep
            written[mode] = _points(f"{name}-{mode}.usdc")
        for prim in PRIMS:
            a, b = written["graph"][prim], written["direct"][prim]
            worst = max(float(np.abs(a[t] - b[t]).max()) for t in a)
            moved = max(float(np.abs(a[t] - a[1.0]).max()) for t in a)
            differs |= worst > 0.0 or sorted(a) != sorted(b)
            print(f"{args.device} field={sdf} preroll={preroll} s {prim}: graph - direct max |dx| {worst:.3g} m "
                  f"(the hair moved up to {moved:.3g} m)", flush=True)
    print("DIFFERENT" if differs else "bit for bit the same")
    return 1 if differs else 0


if __name__ == "__main__":
    sys.exit(main())
