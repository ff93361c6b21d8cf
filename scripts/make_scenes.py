"""Generate the example stages in ``scenes/`` (deterministic; see scenes/README.md).

    python scripts/make_scenes.py [--out scenes]

Each scene is a small, self-contained .usda stage: BasisCurves hair under an (often animated)
transform, optional colliders (UsdPhysics.CollisionAPI) and ``dftl:`` settings.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from pxr import Gf, Sdf, Usd, UsdGeom, UsdPhysics, UsdShade, Vt

ROOT = Path(__file__).resolve().parent.parent


def _stage(path: Path, *, up: str, meters_per_unit: float, start: int, end: int, fps: float = 24.0):
    path.parent.mkdir(parents=True, exist_ok=True)
    if path.exists():
        path.unlink()
    stage = Usd.Stage.CreateNew(str(path))
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.z if up == "Z" else UsdGeom.Tokens.y)
    UsdGeom.SetStageMetersPerUnit(stage, meters_per_unit)
    stage.SetTimeCodesPerSecond(fps)
    stage.SetStartTimeCode(start)
    stage.SetEndTimeCode(end)
    world = UsdGeom.Xform.Define(stage, "/World")
    stage.SetDefaultPrim(world.GetPrim())
    return stage


def _curves(stage, path: str, strands: list[np.ndarray], *, width: float, curve_type="linear",
            basis=None, colors=None, wrap=UsdGeom.Tokens.nonperiodic):
    """A BasisCurves prim from a list of (n_i, 3) strands (root first)."""
    curves = UsdGeom.BasisCurves.Define(stage, path)
    points = np.concatenate(strands).round(4)
    curves.CreateTypeAttr(curve_type)
    if basis:
        curves.CreateBasisAttr(basis)
    curves.CreateWrapAttr(wrap)
    curves.CreateCurveVertexCountsAttr(Vt.IntArray([int(len(s)) for s in strands]))
    curves.CreatePointsAttr(Vt.Vec3fArray.FromNumpy(points.astype(np.float32)))
    curves.CreateWidthsAttr(Vt.FloatArray([width]))
    curves.SetWidthsInterpolation(UsdGeom.Tokens.constant)
    if colors is not None:
        pv = curves.CreateDisplayColorPrimvar(UsdGeom.Tokens.uniform)
        pv.Set(Vt.Vec3fArray.FromNumpy(np.asarray(colors, dtype=np.float32).round(3)))
    lo, hi = points.min(axis=0) - width, points.max(axis=0) + width
    curves.CreateExtentAttr(Vt.Vec3fArray([Gf.Vec3f(*map(float, lo)), Gf.Vec3f(*map(float, hi))]))
    return curves


def _collider(prim, friction=None):
    UsdPhysics.CollisionAPI.Apply(prim)
    if friction is not None:
        prim.CreateAttribute("dftl:friction", Sdf.ValueTypeNames.Float).Set(float(friction))


def _set(prim, name, type_name, value):
    prim.CreateAttribute(name, type_name, custom=True).Set(value)


def _draped(root, normal, length, count, centre, radius, down, rng, droop=2.5):
    """A strand leaving the scalp along its normal and bending towards ``down``, kept outside a
    sphere of ``radius`` around ``centre``."""
    seg = length / (count - 1)
    pts = [root]
    p = root.copy()
    for k in range(1, count):
        t = k / (count - 1)
        d = normal * (1.0 - t) + down * droop * t + rng.normal(scale=0.08, size=3)
        d /= np.linalg.norm(d)
        q = p + seg * d
        r = np.linalg.norm(q - centre)
        if r < radius:
            q = centre + (q - centre) * (radius / r)
            q = p + seg * (q - p) / np.linalg.norm(q - p)
        pts.append(q)
        p = q
    return np.array(pts)


def _sphere_directions(n, rng):
    v = rng.normal(size=(n, 3))
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def make_default(path: Path, *, strands=3000, vertices=16, seed=1):
    """Head with a few thousand strands, turning left and right (centimetres, Y up)."""
    rng = np.random.default_rng(seed)
    stage = _stage(path, up="Y", meters_per_unit=0.01, start=1, end=72)
    head = UsdGeom.Xform.Define(stage, "/World/Head")
    turn = head.AddRotateYOp()
    for frame, angle in ((1, 0.0), (18, 70.0), (42, -70.0), (60, 0.0), (72, 0.0)):
        turn.Set(angle, frame)
    head.AddTranslateOp().Set(Gf.Vec3d(0.0, 160.0, 0.0))

    radius = 9.0
    skull = UsdGeom.Sphere.Define(stage, "/World/Head/Skull")
    skull.CreateRadiusAttr(radius)
    skull.CreateExtentAttr([(-radius,) * 3, (radius,) * 3])
    skull.CreateDisplayColorAttr([(0.85, 0.68, 0.58)])
    _collider(skull.GetPrim(), friction=0.3)

    # roots on the scalp: upper head and back, not the face (+Z)
    dirs = []
    while len(dirs) < strands:
        for n in _sphere_directions(4 * strands, rng):
            scalp = n[1] > 0.1 or (n[2] < -0.2 and n[1] > -0.6)
            face = n[2] > 0.35 and n[1] < 0.45
            if scalp and not face:
                dirs.append(n)
    dirs = np.array(dirs[:strands])
    down = np.array([0.0, -1.0, 0.0])
    lengths = rng.uniform(14.0, 24.0, size=strands)
    strands_pts = [
        _draped(radius * 1.001 * n, n, length, vertices, np.zeros(3), radius * 1.02, down, rng)
        for n, length in zip(dirs, lengths)
    ]
    colors = np.array([0.32, 0.2, 0.11]) * rng.uniform(0.7, 1.3, size=(strands, 1))
    _curves(stage, "/World/Head/Hair", strands_pts, width=0.06, colors=colors.clip(0, 1))
    stage.GetRootLayer().Save()


def make_chain(path: Path, *, links=20, seed=2):
    """A hanging chain released horizontally (metres, Z up, static root)."""
    stage = _stage(path, up="Z", meters_per_unit=1.0, start=1, end=96)
    anchor = UsdGeom.Xform.Define(stage, "/World/Anchor")
    anchor.AddTranslateOp().Set(Gf.Vec3d(0.0, 0.0, 2.0))
    chain = np.zeros((links + 1, 3))
    chain[:, 0] = np.arange(links + 1) * 0.05
    curves = _curves(stage, "/World/Anchor/Chain", [chain], width=0.02, colors=[(0.6, 0.6, 0.65)])
    _set(curves.GetPrim(), "dftl:substeps", Sdf.ValueTypeNames.Int, 16)
    # a chain of links, not hair: no bending stiffness (widths only size it for rendering)
    _set(curves.GetPrim(), "dftl:bending", Sdf.ValueTypeNames.Bool, False)
    stage.GetRootLayer().Save()


def make_ponytail(path: Path, *, strands=600, vertices=20, seed=3):
    """A ponytail swinging from a bobbing, turning head; cubic Catmull-Rom curves (metres, Y up)."""
    rng = np.random.default_rng(seed)
    stage = _stage(path, up="Y", meters_per_unit=1.0, start=1, end=96)
    head = UsdGeom.Xform.Define(stage, "/World/Head")
    move = head.AddTranslateOp()
    for frame in range(1, 97, 6):
        move.Set(Gf.Vec3d(0.0, round(1.6 + 0.04 * np.sin(frame / 6.0 * np.pi), 4), 0.0), frame)
    turn = head.AddRotateYOp()
    for frame, angle in ((1, 0.0), (30, 45.0), (60, -45.0), (96, 0.0)):
        turn.Set(angle, frame)

    # the tie at the back of the head, strands hanging down the back
    tie = np.array([0.0, 0.05, -0.11])
    r = 0.012 * np.sqrt(rng.uniform(size=strands))
    a = rng.uniform(0, 2 * np.pi, size=strands)
    roots = tie + np.stack([r * np.cos(a), r * np.sin(a), np.zeros(strands)], axis=1)
    lengths = rng.uniform(0.3, 0.4, size=strands)
    out = np.array([0.0, 0.3, -1.0])
    out /= np.linalg.norm(out)
    tail = [
        _draped(p, out, length, vertices, np.array([0.0, 0.0, 0.0]), 0.1, np.array([0.0, -1.0, -0.15]), rng, droop=3.0)
        for p, length in zip(roots, lengths)
    ]
    colors = np.array([0.75, 0.55, 0.25]) * rng.uniform(0.8, 1.2, size=(strands, 1))
    curves = _curves(stage, "/World/Head/Ponytail", tail, width=0.0015, curve_type="cubic",
                     basis="catmullRom", colors=colors.clip(0, 1),
                     wrap=UsdGeom.Tokens.pinned)  # drawn from the root the simulation pins
    _set(curves.GetPrim(), "dftl:damping", Sdf.ValueTypeNames.Float, 0.9)

    skull = UsdGeom.Sphere.Define(stage, "/World/Head/Skull")
    skull.CreateRadiusAttr(0.1)
    skull.CreateExtentAttr([(-0.1,) * 3, (0.1,) * 3])
    _collider(skull.GetPrim())
    neck = UsdGeom.Capsule.Define(stage, "/World/Head/Neck")
    neck.CreateRadiusAttr(0.05)
    neck.CreateHeightAttr(0.12)
    neck.CreateAxisAttr(UsdGeom.Tokens.y)
    neck.AddTranslateOp().Set(Gf.Vec3d(0.0, -0.15, -0.01))
    _collider(neck.GetPrim())
    # a physics material gives the neck its friction
    material = UsdShade.Material.Define(stage, "/World/Materials/Skin")
    mat = UsdPhysics.MaterialAPI.Apply(material.GetPrim())
    mat.CreateDynamicFrictionAttr(0.4)
    mat.CreateStaticFrictionAttr(0.5)
    UsdShade.MaterialBindingAPI.Apply(neck.GetPrim()).Bind(
        material, UsdShade.Tokens.weakerThanDescendants, "physics")
    stage.GetRootLayer().Save()


def make_furball(path: Path, *, strands=2000, seed=4):
    """A fur ball hopping and spinning; cubic Bezier fur (7 control points), a physics scene
    with gravity at half strength (metres, Y up)."""
    rng = np.random.default_rng(seed)
    stage = _stage(path, up="Y", meters_per_unit=1.0, start=1, end=72)
    physics = UsdPhysics.Scene.Define(stage, "/World/Physics")
    physics.CreateGravityDirectionAttr(Gf.Vec3f(0.0, -1.0, 0.0))
    physics.CreateGravityMagnitudeAttr(4.9)
    ball = UsdGeom.Xform.Define(stage, "/World/Ball")
    move = ball.AddTranslateOp()
    for frame in range(1, 73, 3):
        t = (frame - 1) / 24.0
        move.Set(Gf.Vec3d(round(0.3 * t, 4), round(0.2 + abs(np.sin(np.pi * t)) * 0.3, 4), 0.0), frame)
    spin = ball.AddRotateZOp()
    spin.Set(0.0, 1)
    spin.Set(-360.0, 72)
    radius = 0.1
    body = UsdGeom.Sphere.Define(stage, "/World/Ball/Body")
    body.CreateRadiusAttr(radius)
    body.CreateExtentAttr([(-radius,) * 3, (radius,) * 3])
    body.CreateDisplayColorAttr([(0.9, 0.5, 0.2)])
    _collider(body.GetPrim())
    fur = []
    for n in _sphere_directions(strands, rng):
        length = rng.uniform(0.04, 0.06)
        t = np.linspace(0.0, 1.0, 7)[:, None]
        fur.append(radius * n + length * t * n)
    colors = np.array([0.95, 0.6, 0.25]) * rng.uniform(0.8, 1.1, size=(strands, 1))
    curves = _curves(stage, "/World/Ball/Fur", fur, width=0.002, curve_type="cubic", basis="bezier",
                     colors=colors.clip(0, 1))
    _set(curves.GetPrim(), "dftl:substeps", Sdf.ValueTypeNames.Int, 6)
    stage.GetRootLayer().Save()


SCENES = {
    "default.usda": make_default,
    "chain.usda": make_chain,
    "ponytail.usda": make_ponytail,
    "furball.usda": make_furball,
}


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default=str(ROOT / "scenes"), help="folder to write the stages to")
    args = parser.parse_args(argv)
    out = Path(args.out)
    for name, make in SCENES.items():
        make(out / name)
        print(out / name)


if __name__ == "__main__":
    main()
