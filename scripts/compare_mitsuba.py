"""Coverage of dftl-warp's renderer against Mitsuba 3 on the same curves and camera.

    python scripts/compare_mitsuba.py [--input STAGE.usda [--camera PRIM] [--frame F]]
                                      [--resolution 480x360] [--spp 64] [--out DIR]

Without --input, a numpy groom (strands on a sphere, no head) is written to OUT/groom.usda
first. Both renderers draw the stage's BasisCurves as tubes with the authored radii:
dftl-warp as round linear curves through its Warp BVH, Mitsuba 3 (pip ``mitsuba``, CPU variant
``scalar_rgb``) with its ``linearcurve`` shape, through the same camera (the USD camera, or the
automatic framing) with a box pixel filter, so that both alphas are pixel coverage. Reports the
IoU of the covered pixels (alpha >= 0.5), a soft IoU (sum min / sum max of the alphas) and the
mean alpha difference; exits 1 if the IoU is below --min-iou (0.9).
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

import numpy as np



def make_groom_stage(path: Path, strands: int, width: float) -> None:
    from pxr import Usd, UsdGeom, Vt

    from dftl_warp.render.groom import sphere_groom

    pts, counts = sphere_groom(strands, 12, radius=0.1, length=0.12, seed=3)
    stage = Usd.Stage.CreateNew(str(path))
    UsdGeom.SetStageUpAxis(stage, "Y")
    c = UsdGeom.BasisCurves.Define(stage, "/groom/hair")
    c.CreateTypeAttr("linear")
    c.CreateCurveVertexCountsAttr(Vt.IntArray(counts.tolist()))
    c.CreatePointsAttr(Vt.Vec3fArray.FromNumpy(pts.astype(np.float32)))
    # tapered: `width` at the root to 40 % of it at the tip (vertex interpolation)
    u = np.tile(np.linspace(0.0, 1.0, 12), strands)
    c.CreateWidthsAttr(Vt.FloatArray((width * (1.0 - 0.6 * u)).tolist()))
    c.SetWidthsInterpolation("vertex")
    stage.Save()


def mitsuba_alpha(scene, camera, width, height, spp, variant, curve_file: Path):
    import mitsuba as mi

    mi.set_variant(variant)
    # Mitsuba's curve file: one "x y z radius" per line, a blank line between curves
    with open(curve_file, "w") as f:
        start = 0
        for n in scene.curve_vertex_counts:
            for p, r in zip(scene.points[start:start + n], scene.radii[start:start + n]):
                f.write(f"{p[0]:.9g} {p[1]:.9g} {p[2]:.9g} {r:.9g}\n")
            f.write("\n")
            start += n
    left, right, bottom, top = camera.screen_window(width, height)
    if abs(left + right) > 1e-9 or abs(bottom + top) > 1e-9:
        raise SystemExit("compare_mitsuba: use a camera without aperture offsets")
    m = np.asarray(camera.world_from_camera, dtype=np.float64)
    eye, forward, up = m[:3, 3], -m[:3, 2], m[:3, 1]
    fov_x = math.degrees(2.0 * math.atan(0.5 * (right - left)))
    sensor = {
        "type": "perspective",
        "fov": fov_x,
        "fov_axis": "x",
        "near_clip": float(camera.near),
        "far_clip": float(camera.far),
        "to_world": mi.ScalarTransform4f().look_at(origin=eye.tolist(), target=(eye + forward).tolist(), up=up.tolist()),
        "film": {"type": "hdrfilm", "width": width, "height": height, "pixel_format": "rgba",
                 "rfilter": {"type": "box"}},
        "sampler": {"type": "stratified", "sample_count": spp},
    }
    mscene = mi.load_dict({
        "type": "scene",
        "integrator": {"type": "direct"},
        "sensor": sensor,
        "hair": {"type": "linearcurve", "filename": str(curve_file), "bsdf": {"type": "diffuse"}},
        "light": {"type": "constant"},
    })
    img = np.array(mi.render(mscene, spp=spp))
    return img[..., 3]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--input", help="USD stage (default: a generated groom)")
    ap.add_argument("--camera", help="camera prim (default: automatic framing)")
    ap.add_argument("--frame", type=float)
    ap.add_argument("--resolution", default="480x360")
    ap.add_argument("--spp", type=int, default=64)
    ap.add_argument("--strands", type=int, default=400, help="strands of the generated groom")
    ap.add_argument("--width", type=float, default=0.003, help="root width of the generated groom (m)")
    ap.add_argument("--variant", default="scalar_rgb", help="Mitsuba variant (CPU: scalar_rgb, llvm_ad_rgb)")
    ap.add_argument("--min-iou", type=float, default=0.9)
    ap.add_argument("--out", default="out/compare_mitsuba")
    args = ap.parse_args(argv)

    from dftl_warp.core.devices import init_warp

    init_warp()
    from dftl_warp.render import Renderer, to_rgba8, usd_scene
    from dftl_warp.render.image import write_png

    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    width, height = (int(v) for v in args.resolution.split("x"))
    path = Path(args.input) if args.input else out / "groom.usda"
    if not args.input:
        make_groom_stage(path, args.strands, args.width)
    stage = usd_scene.open_stage(path)
    scene = usd_scene.read_render_scene(stage, args.frame, str(path))
    renderer = Renderer(width, height, spp=args.spp, min_pixel_width=0)   # true widths, as Mitsuba draws them
    camera = usd_scene.read_camera(stage, args.camera, args.frame) if args.camera else renderer.default_camera(scene)

    t0 = time.perf_counter()
    ours = renderer.render(scene, camera)
    t_ours = time.perf_counter() - t0
    t0 = time.perf_counter()
    theirs = mitsuba_alpha(scene, camera, width, height, args.spp, args.variant, out / "curves.txt")
    t_theirs = time.perf_counter() - t0

    a, b = ours[..., 3], np.clip(theirs, 0.0, 1.0)
    ma, mb = a >= 0.5, b >= 0.5
    iou = float((ma & mb).sum() / max((ma | mb).sum(), 1))
    soft = float(np.minimum(a, b).sum() / max(np.maximum(a, b).sum(), 1e-12))
    mad = float(np.abs(a - b).mean())
    write_png(out / "dftl_warp.png", to_rgba8(ours))
    write_png(out / "mitsuba_alpha.png", np.dstack([np.full(b.shape + (3,), 255, np.uint8), np.round(b * 255).astype(np.uint8)]))
    diff = np.zeros(a.shape + (4,), np.uint8)
    diff[..., 0] = np.round(np.clip(a - b, 0, 1) * 255)   # red: only dftl-warp
    diff[..., 1] = np.round(np.clip(b - a, 0, 1) * 255)   # green: only Mitsuba
    diff[..., 2] = np.round(np.minimum(a, b) * 255)       # blue: both
    diff[..., 3] = 255
    write_png(out / "coverage_diff.png", diff)
    line = (f"| {path.name} | {scene.strand_count} strands, {scene.segment_count} segments | {width}x{height} | {args.spp} "
            f"| {iou:.4f} | {soft:.4f} | {mad:.4f} | {a.sum():.0f} / {b.sum():.0f} |")
    print(f"coverage IoU (alpha >= 0.5): {iou:.4f}   soft IoU: {soft:.4f}   mean |alpha diff|: {mad:.4f}")
    print(f"covered pixels: dftl-warp {a.sum():.1f}, Mitsuba {b.sum():.1f}; times {t_ours:.1f} s / {t_theirs:.1f} s")
    print("| stage | curves | resolution | spp | IoU | soft IoU | mean abs alpha diff | coverage (px) dftl-warp / Mitsuba |")
    print("|---|---|---|---|---|---|---|---|")
    print(line)
    (out / "result.md").write_text(line + "\n")
    return 0 if iou >= args.min_iou else 1


if __name__ == "__main__":
    sys.exit(main())
