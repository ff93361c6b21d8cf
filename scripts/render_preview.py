"""The README's preview: a numpy groom on a sphere 'head', rendered by dftl-warp's renderer.

    python scripts/render_preview.py [--device cpu] [--out docs/img/preview.png]
                                     [--root-width 0.0005] [--min-pixel-width W]

Writes the groom as a USD stage (OUT's folder/.. is not touched: the stage goes to
out/preview/groom.usda) and renders it with the same code as ``dftl-warp render``.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np


def write_stage(path: Path, strands: int, vertices: int, root_width: float = 0.0005) -> None:
    from pxr import Gf, Usd, UsdGeom, Vt

    from dftl_warp.render.groom import sphere_groom

    pts, counts = sphere_groom(strands, vertices, radius=0.1, length=0.16, seed=7, curl=0.006)
    path.parent.mkdir(parents=True, exist_ok=True)
    stage = Usd.Stage.CreateNew(str(path))
    UsdGeom.SetStageUpAxis(stage, "Y")
    UsdGeom.SetStageMetersPerUnit(stage, 1.0)
    c = UsdGeom.BasisCurves.Define(stage, "/groom/hair")
    c.CreateTypeAttr("linear")
    c.CreateCurveVertexCountsAttr(Vt.IntArray(counts.tolist()))
    c.CreatePointsAttr(Vt.Vec3fArray.FromNumpy(pts.astype(np.float32)))
    u = np.tile(np.linspace(0.0, 1.0, vertices), strands)
    c.CreateWidthsAttr(Vt.FloatArray((root_width * (1.0 - 0.6 * u)).tolist()))
    c.SetWidthsInterpolation("vertex")
    head = UsdGeom.Sphere.Define(stage, "/groom/head")
    head.CreateRadiusAttr(0.1)
    cam = UsdGeom.Camera.Define(stage, "/camera")
    cam.AddTranslateOp().Set(Gf.Vec3d(0.0, -0.045, 0.0))
    cam.AddRotateYOp().Set(-50.0)
    cam.AddRotateXOp().Set(-8.0)
    cam.AddTranslateOp(opSuffix="dolly").Set(Gf.Vec3d(0.0, 0.0, 0.78))
    cam.CreateFocalLengthAttr(50.0)
    cam.CreateHorizontalApertureAttr(36.0)
    cam.CreateVerticalApertureAttr(24.0)
    cam.CreateClippingRangeAttr(Gf.Vec2f(0.1, 10.0))
    stage.Save()


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--device", default="cpu")
    ap.add_argument("--out", default="docs/img/preview.png")
    ap.add_argument("--strands", type=int, default=15000)
    ap.add_argument("--resolution", default="720x540")
    ap.add_argument("--spp", type=int, default=16)
    ap.add_argument("--root-width", type=float, default=0.0005,
                    help="strand width at the root in metres, tapering to 40 %% at the tip (real hair: 4e-5 to 1e-4)")
    ap.add_argument("--min-pixel-width", default=None, help="passed to dftl-warp render (default: its default)")
    args = ap.parse_args(argv)
    stage = Path("out/preview/groom.usda")
    write_stage(stage, args.strands, 24, args.root_width)
    from dftl_warp import cli

    t0 = time.perf_counter()
    extra = [] if args.min_pixel_width is None else ["--min-pixel-width", args.min_pixel_width]
    rc = cli.main(["render", str(stage), "--camera", "/camera", "--resolution", args.resolution,
                   "--spp", str(args.spp), "--device", args.device, *extra, "-o", args.out])
    print(f"{args.out}: {time.perf_counter() - t0:.1f} s")
    return rc


if __name__ == "__main__":
    sys.exit(main())
