"""Makes docs/guides/before_after.png (issue 22): a sphere head with 24 guide strands (red, thick)
driving 600 curly render strands (brown, rel dftl:guides), the head turning 90 deg about Y over
24 frames; simulated with ``dftl-warp simulate`` and rendered with ``dftl-warp render``.

    .venv/bin/python docs/guides/picture.py OUTDIR
"""

import subprocess
import sys
from pathlib import Path

import numpy as np
from pxr import Gf, Sdf, Usd, UsdGeom, UsdPhysics, Vt

out = Path(sys.argv[1])
out.mkdir(parents=True, exist_ok=True)
rng = np.random.default_rng(1)
N = 12


def strand(root, normal, length, curl, phase):
    side = np.cross(normal, [0, 1, 0])
    side = side / (np.linalg.norm(side) + 1e-9)
    up = np.cross(side, normal)
    pts = []
    for i in range(N):
        s = i / (N - 1)
        d = normal + np.array([0.0, -0.3, 0.0])
        p = root + length * s * d / np.linalg.norm(d)
        p = p + curl * s * (np.cos(10 * s + phase) * side + np.sin(10 * s + phase) * up)
        pts.append(p)
    return pts


def scalp(n):
    v = rng.normal(size=(n, 3))
    v[:, 1] = np.abs(v[:, 1]) + 0.2
    return v / np.linalg.norm(v, axis=1)[:, None]


stage = Usd.Stage.CreateNew(str(out / "groom.usda"))
UsdGeom.SetStageUpAxis(stage, "Y")
UsdGeom.SetStageMetersPerUnit(stage, 1.0)
stage.SetStartTimeCode(1)
stage.SetEndTimeCode(24)
stage.SetTimeCodesPerSecond(24)
UsdGeom.Xform.Define(stage, "/World")
stage.SetDefaultPrim(stage.GetPrimAtPath("/World"))
head = UsdGeom.Xform.Define(stage, "/World/Head")
op = head.AddRotateYOp()
op.Set(0.0, 1)
op.Set(90.0, 24)
ball = UsdGeom.Sphere.Define(stage, "/World/Head/Skull")
ball.CreateRadiusAttr(0.09)
UsdPhysics.CollisionAPI.Apply(ball.GetPrim())
R = 0.1
for name, n, length, curl, width, color in (("Guides", 24, 0.3, 0.0, 0.004, (0.8, 0.1, 0.1)),
                                            ("Hair", 600, 0.3, 0.012, 0.0012, (0.35, 0.22, 0.12))):
    dirs = scalp(n) if name == "Hair" else scalp(n)
    pts = []
    for d in dirs:
        pts += strand(R * d, d, length * rng.uniform(0.85, 1.1), curl, rng.uniform(0, 6.28))
    c = UsdGeom.BasisCurves.Define(stage, f"/World/Head/{name}")
    c.CreateTypeAttr("linear")
    c.CreateCurveVertexCountsAttr(Vt.IntArray([N] * n))
    c.CreatePointsAttr(Vt.Vec3fArray.FromNumpy(np.array(pts, dtype=np.float32)))
    c.CreateWidthsAttr(Vt.FloatArray([width]))
    c.SetWidthsInterpolation("constant")
    c.CreateDisplayColorAttr(Vt.Vec3fArray([Gf.Vec3f(*color)]))
stage.GetPrimAtPath("/World/Head/Hair").CreateRelationship("dftl:guides").SetTargets([Sdf.Path("/World/Head/Guides")])
stage.Save()
run = [sys.executable, "-m", "dftl_warp"]
subprocess.run([*run, "simulate", str(out / "groom.usda"), "-o", str(out / "sim.usdc"), "--device", "cpu"], check=True)
subprocess.run([*run, "render", str(out / "sim.usdc"), "--start", "1", "--end", "24", "--step", "23",
                "--contact-sheet", "--resolution", "480x400", "--spp", "4", "--device", "cpu",
                "-o", str(out / "before_after.png")], check=True)
