#!/usr/bin/env python
"""Does a real groom keep its style? Set a groom up as a pipeline TD would, simulate it with
``dftl-warp simulate`` and measure the style metrics of issue 17 ("Real grooms").

    python scripts/groom_style_check.py GROOM.usda [--head auto|none|sphere|MESH.obj|MESH.ply]
        [--motion static|turn] [--frames 48] [--fps F [--resolution-every K]] [--device cpu]
        [--json out.json] [--markdown out.md] [--sheet before_after.png] [--label NAME]
        [--keep DIR] [any other flag of `dftl-warp simulate`, e.g. --solver pbd --substeps 4]

GROOM.usda is a stage with BasisCurves under its default prim, e.g. the output of
``dftl-warp import`` (docs/import.md, docs/grooms.md). In a temporary folder (``--keep DIR`` keeps
it) the script writes a wrapper stage:

    /World                  (the groom's upAxis, metersPerUnit, timeCodesPerSecond)
      /World/Pivot          Xform: static, or with --motion turn a rotation about the up axis
                            through the head centre of 60 sin(2 pi t / 2 s) degrees (±60 over 2 s)
        /World/Pivot/Groom  references the groom's default prim (its head Mesh collider included)
        /World/Pivot/HeadSphere   with --head sphere: a Sphere with PhysicsCollisionAPI fitted to
                            the roots (the groom's own colliders are deactivated)
        /World/Pivot/HeadMesh     with --head MESH: that mesh with PhysicsCollisionAPI
      /World/Camera         a fixed 3/4 view of the groom at frame 1 (for the contact sheet)

(``--shape-stiffness``, which authored the retired ``dftl:shapeStiffness``, made the baseline rows of
docs/grooms.md; the reader now refuses that attribute.) It runs ``dftl-warp simulate`` (frames 1..--frames) and measures, on
the written time samples:

- tip displacement: per strand, the largest distance over the run of the tip from its authored
  position, in the prim's local space (the head's frame), over the strand's length; median and
  p90 over strands (also at the last frame alone);
- curl radius retention: per curly strand (authored turning >= 270 degrees), the radius of the least-squares circle through its points
  projected on the plane normal to its principal axis (PCA), last frame over first; median over
  strands with at least 8 points;
- crest standing: the share of strands whose tip is above its root along the up axis, first and
  last frame;
- jitter ratio: mean |x(f+1) - 2x(f) + x(f-1)| over mean |x(f+1) - x(f-1)|/2, world space, every
  non-root point and inner frame (smooth motion < 1);
- velocity consistency: |written velocity| / |central difference of written points| (both local,
  as USD defines velocities), over non-root points of inner frames whose central difference is at
  least 1% of its p99; p1, median and p99.

With ``--fps F --resolution-every K`` (e.g. 96 and 4, with ``--frames`` and ``--substeps`` scaled
to keep the run's length and substep) it also says whether F/K frames per second resolve the
hair's local motion: the share of its velocity power above F/2K Hz, and the velocity ratio at
every K-th frame against the central difference at F/K and at F frames per second.

It writes the numbers as JSON (``--json``) and a markdown table row (``--markdown``, appended),
prints both, and with ``--sheet`` renders frame 1 and the last frame side by side into one PNG
(``dftl-warp render`` of the two frames, combined with Pillow, at most 800 px wide).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import shutil
import subprocess
import sys
import tempfile
import time

import numpy as np


def dftl_warp_cmd() -> list[str]:
    exe = os.path.join(os.path.dirname(sys.executable), "dftl-warp")
    return [exe] if os.path.exists(exe) else [sys.executable, "-m", "dftl_warp"]


# ----------------------------------------------------------------------------- scene set-up

def read_groom(path):
    """(stage, default prim path, list of (curves prim, points, counts) in local space)."""
    from pxr import Usd, UsdGeom
    stage = Usd.Stage.Open(path)
    if stage is None:
        raise SystemExit(f"{path}: cannot open")
    root = stage.GetDefaultPrim()
    if not root:
        raise SystemExit(f"{path}: no defaultPrim; the wrapper references the default prim")
    curves = []
    for prim in Usd.PrimRange(root):
        if prim.IsA(UsdGeom.BasisCurves):
            c = UsdGeom.BasisCurves(prim)
            pts = np.asarray(c.GetPointsAttr().Get(stage.GetStartTimeCode()), dtype=np.float64)
            cnt = np.asarray(c.GetCurveVertexCountsAttr().Get(), dtype=np.int64)
            xf = np.array(UsdGeom.Xformable(prim).ComputeLocalToWorldTransform(stage.GetStartTimeCode()))
            curves.append((prim.GetPath(), pts, cnt, xf))
    if not curves:
        raise SystemExit(f"{path}: no BasisCurves under the default prim {root.GetPath()}")
    return stage, root, curves


def apply_row_matrix(m, pts):
    """USD row-vector 4x4 matrix applied to (N, 3) points."""
    return pts @ m[:3, :3] + m[3, :3]


def roots_tips(points, counts):
    off = np.concatenate([[0], np.cumsum(counts)[:-1]])
    return off, off + counts - 1


def fit_sphere(p):
    """Least-squares sphere through points; falls back to the mean when ill-conditioned.
    Returns centre, radius (a little inside the roots so none starts in contact)."""
    c0 = p.mean(axis=0)
    q = p - c0
    sd = np.sqrt(np.linalg.eigvalsh(np.cov(q.T)))
    A = np.c_[2 * q, np.ones(len(q))]
    b = (q * q).sum(axis=1)
    sol, *_ = np.linalg.lstsq(A, b, rcond=None)
    centre = c0 + sol[:3]
    r_fit = math.sqrt(max(sol[3] + sol[:3] @ sol[:3], 0.0))
    if not np.isfinite(r_fit) or r_fit > 5 * sd.max() or sd.min() < 0.2 * sd.max():
        # roots on a strip or nearly flat: no sphere can be fitted well; note it
        print(f"groom_style_check: warning: roots are not spread over a cap (sd {sd.round(4)}); "
              "the fitted sphere is a rough guess", file=sys.stderr)
    d = np.linalg.norm(p - centre, axis=1)
    return centre, 0.97 * float(np.percentile(d, 10))


def write_wrapper(groom_path, folder, args):
    from pxr import Gf, Sdf, Usd, UsdGeom, UsdPhysics, Vt
    gstage, groot, curves = read_groom(groom_path)
    up = UsdGeom.GetStageUpAxis(gstage)
    mpu = UsdGeom.GetStageMetersPerUnit(gstage)
    tcps = args.fps or gstage.GetTimeCodesPerSecond()
    start = 1
    end = start + args.frames - 1

    # roots, tips in the groom's world space (frame start) for the head fit and the camera
    allpts = np.concatenate([apply_row_matrix(xf, p) for _, p, _, xf in curves])
    roots = np.concatenate([apply_row_matrix(xf, p)[roots_tips(p, c)[0]] for _, p, c, xf in curves])

    stage = Usd.Stage.CreateNew(os.path.join(folder, "scene.usda"))
    UsdGeom.SetStageUpAxis(stage, up)
    UsdGeom.SetStageMetersPerUnit(stage, mpu)
    stage.SetTimeCodesPerSecond(tcps)
    stage.SetStartTimeCode(start)
    stage.SetEndTimeCode(end)
    world = UsdGeom.Xform.Define(stage, "/World")
    stage.SetDefaultPrim(world.GetPrim())
    pivot = UsdGeom.Xform.Define(stage, "/World/Pivot")
    groom = stage.DefinePrim("/World/Pivot/Groom")
    groom.GetReferences().AddReference(os.path.abspath(groom_path))
    gpath = groom.GetPath()

    # colliders already in the groom
    own = [p for p in Usd.PrimRange(groot) if p.HasAPI(UsdPhysics.CollisionAPI)]
    own_paths = [gpath.AppendPath(p.GetPath().MakeRelativePath(groot.GetPath())) for p in own]

    centre, radius = fit_sphere(roots)
    head_desc = "none"
    if args.head in ("none", "sphere") or os.path.splitext(args.head)[1].lower() in (".obj", ".ply"):
        for p in own_paths:
            stage.OverridePrim(p).SetActive(False)
    if args.head == "auto":
        head_desc = ", ".join(str(p.GetPath()) for p in own) + " (groom's own)" if own else "none"
    elif args.head == "sphere":
        s = UsdGeom.Sphere.Define(stage, "/World/Pivot/HeadSphere")
        s.CreateRadiusAttr(radius)
        s.AddTranslateOp().Set(Gf.Vec3d(*centre))
        UsdPhysics.CollisionAPI.Apply(s.GetPrim())
        head_desc = f"sphere r={radius:.4g} at ({centre[0]:.4g}, {centre[1]:.4g}, {centre[2]:.4g})"
    elif args.head != "none":
        from dftl_warp.importers.meshes import read_mesh
        md = read_mesh(args.head)
        for note in md.warnings:   # what the OBJ reader skipped, as `dftl-warp import --head` says it
            print(f"warning: {note}", file=sys.stderr)
        hp = np.asarray(md.points, dtype=np.float64)
        if args.head_x_up:  # as `dftl-warp import --up-axis X`: (x, y, z) -> (-y, x, z)
            hp = np.c_[-hp[:, 1], hp[:, 0], hp[:, 2]]
        m = UsdGeom.Mesh.Define(stage, "/World/Pivot/HeadMesh")
        m.CreatePointsAttr(Vt.Vec3fArray.FromNumpy(hp.astype(np.float32)))
        m.CreateFaceVertexCountsAttr(Vt.IntArray.FromNumpy(np.asarray(md.face_counts, dtype=np.int32)))
        m.CreateFaceVertexIndicesAttr(Vt.IntArray.FromNumpy(np.asarray(md.face_indices, dtype=np.int32)))
        m.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)
        UsdPhysics.CollisionAPI.Apply(m.GetPrim())
        head_desc = f"mesh {os.path.basename(args.head)}"
        centre = 0.5 * (hp.min(axis=0) + hp.max(axis=0))

    if args.motion == "turn":
        # rotate about the up axis through the head centre
        pivot.AddTranslateOp(opSuffix="pivot").Set(Gf.Vec3d(*centre))
        rot = pivot.AddRotateZOp() if up == UsdGeom.Tokens.z else pivot.AddRotateYOp()
        for f in range(start, end + 1):
            t = (f - start) / tcps
            rot.Set(args.turn_degrees * math.sin(2 * math.pi * t / args.turn_period), Usd.TimeCode(f))
        pivot.AddTranslateOp(opSuffix="pivotInv").Set(Gf.Vec3d(*(-centre)))

    # a fixed camera: 3/4 view of hair (+ head) at the start
    lo, hi = allpts.min(axis=0), allpts.max(axis=0)
    bc = 0.5 * (lo + hi)
    rad = 0.5 * float(np.linalg.norm(hi - lo))
    upv = np.array([0, 0, 1.0]) if up == UsdGeom.Tokens.z else np.array([0, 1.0, 0])
    view = np.array([0.8, 0.25, 1.0]) if up != UsdGeom.Tokens.z else np.array([0.8, -1.0, 0.25])
    view /= np.linalg.norm(view)
    focal, aperture = 50.0, 36.0
    dist = 0.95 * rad / math.sin(math.atan(0.5 * aperture / focal))
    eye = bc + dist * view
    cam = UsdGeom.Camera.Define(stage, "/World/Camera")
    cam.CreateFocalLengthAttr(focal)
    cam.CreateHorizontalApertureAttr(aperture)
    cam.CreateVerticalApertureAttr(aperture)
    cam.CreateClippingRangeAttr(Gf.Vec2f(dist * 0.01, dist * 10))
    look = Gf.Matrix4d().SetLookAt(Gf.Vec3d(*eye), Gf.Vec3d(*bc), Gf.Vec3d(*upv))
    cam.AddTransformOp().Set(look.GetInverse())
    stage.GetRootLayer().Save()
    return stage.GetRootLayer().realPath, dict(view_width=2 * rad / 300, up=str(up), meters_per_unit=mpu, fps=tcps, start=start,
                                               end=end, head=head_desc)


# ----------------------------------------------------------------------------- measuring

def read_output(path, start, end):
    """Per BasisCurves prim with time samples: local points (F, N, 3), velocities (F, N, 3),
    world points (F, N, 3), counts, authored local points."""
    from pxr import Usd, UsdGeom
    stage = Usd.Stage.Open(path)
    out = []
    for prim in stage.Traverse():
        if not prim.IsA(UsdGeom.BasisCurves):
            continue
        c = UsdGeom.BasisCurves(prim)
        if c.GetPointsAttr().GetNumTimeSamples() == 0:
            continue
        cnt = np.asarray(c.GetCurveVertexCountsAttr().Get(), dtype=np.int64)
        authored = np.asarray(c.GetPointsAttr().Get(Usd.TimeCode.Default()), dtype=np.float64)
        loc, vel, wor = [], [], []
        for f in range(start, end + 1):
            t = Usd.TimeCode(f)
            p = np.asarray(c.GetPointsAttr().Get(t), dtype=np.float64)
            v = np.asarray(c.GetVelocitiesAttr().Get(t), dtype=np.float64)
            m = np.array(UsdGeom.Xformable(prim).ComputeLocalToWorldTransform(t))
            loc.append(p)
            vel.append(v)
            wor.append(apply_row_matrix(m, p))
        out.append(dict(path=str(prim.GetPath()), counts=cnt, authored=authored, local=np.array(loc),
                        vel=np.array(vel), world=np.array(wor)))
    if not out:
        raise SystemExit(f"{path}: no simulated BasisCurves")
    return out


def strand_lengths(points, counts):
    seg = np.linalg.norm(np.diff(points, axis=0), axis=1)
    off = np.concatenate([[0], np.cumsum(counts)])
    cs = np.concatenate([[0], np.cumsum(seg)])
    # sum of segments within each strand: cs[last] - cs[first]
    return cs[off[1:] - 1] - cs[off[:-1]]


def circle_radius(p):
    """Radius of the least-squares circle of p projected on the plane normal to p's principal axis."""
    q = p - p.mean(axis=0)
    _, _, vt = np.linalg.svd(q, full_matrices=False)
    uv = q @ vt[1:3].T
    A = np.c_[2 * uv, np.ones(len(uv))]
    b = (uv * uv).sum(axis=1)
    sol, *_ = np.linalg.lstsq(A, b, rcond=None)
    r2 = sol[2] + sol[0] ** 2 + sol[1] ** 2
    return math.sqrt(r2) if r2 > 0 else float("nan")


def turning_degrees(p):
    """Total turning angle of a polyline (degrees): a strand with >= 270 counts as curly."""
    t = np.diff(p, axis=0)
    t /= np.maximum(np.linalg.norm(t, axis=1), 1e-30)[:, None]
    return float(np.degrees(np.arccos(np.clip((t[1:] * t[:-1]).sum(axis=1), -1, 1)).sum()))


def measure(prims, up_index, fps):
    tipdisp_max, tipdisp_end, curl, up0, up1 = [], [], [], [], []
    acc_num = acc_den = 0.0
    n_acc = 0
    ratios = []
    for d in prims:
        cnt, loc, wor, vel = d["counts"], d["local"], d["world"], d["vel"]
        first, last = roots_tips(d["authored"], cnt)
        L = strand_lengths(d["authored"], cnt)
        tips = loc[:, last, :]                                  # (F, S, 3)
        disp = np.linalg.norm(tips - d["authored"][last][None], axis=2) / L[None]
        tipdisp_max.append(disp.max(axis=0))
        tipdisp_end.append(disp[-1])
        off = np.concatenate([[0], np.cumsum(cnt)])
        for s in range(len(cnt)):
            if cnt[s] >= 8 and turning_degrees(d["authored"][off[s]:off[s + 1]]) >= 270:
                r0 = circle_radius(loc[0, off[s]:off[s + 1]])
                r1 = circle_radius(loc[-1, off[s]:off[s + 1]])
                if np.isfinite(r0) and np.isfinite(r1) and r0 > 0:
                    curl.append(r1 / r0)
        up0.append(loc[0, last, up_index] > loc[0, first, up_index])
        up1.append(loc[-1, last, up_index] > loc[-1, first, up_index])
        nonroot = np.ones(len(d["authored"]), dtype=bool)
        nonroot[first] = False
        if len(wor) >= 3:
            w = wor[:, nonroot]
            acc = np.linalg.norm(w[2:] - 2 * w[1:-1] + w[:-2], axis=2)
            cd = np.linalg.norm(w[2:] - w[:-2], axis=2) / 2
            acc_num += acc.sum()
            acc_den += cd.sum()
            n_acc += acc.size
            lc = loc[:, nonroot]
            cdl = (lc[2:] - lc[:-2]) * fps / 2                  # local central difference, units/s
            vl = vel[1:-1][:, nonroot]
            ncd = np.linalg.norm(cdl, axis=2).ravel()
            nv = np.linalg.norm(vl, axis=2).ravel()
            ratios.append((nv, ncd))
    tdm = np.concatenate(tipdisp_max)
    tde = np.concatenate(tipdisp_end)
    up0, up1 = np.concatenate(up0), np.concatenate(up1)
    res = dict(
        strands=int(tdm.size),
        tip_disp_median=float(np.median(tdm)), tip_disp_p90=float(np.percentile(tdm, 90)),
        tip_disp_end_median=float(np.median(tde)), tip_disp_end_p90=float(np.percentile(tde, 90)),
        curl_ratio_median=float(np.median(curl)) if curl else None,
        curl_ratio_p10=float(np.percentile(curl, 10)) if curl else None,
        curl_ratio_p90=float(np.percentile(curl, 90)) if curl else None,
        curl_strands=len(curl),
        crest_up_start=float(up0.mean()), crest_up_end=float(up1.mean()),
        jitter_ratio=float(acc_num / acc_den) if acc_den > 0 else None,
    )
    if ratios:
        nv = np.concatenate([r[0] for r in ratios])
        ncd = np.concatenate([r[1] for r in ratios])
        keep = ncd >= 0.01 * np.percentile(ncd, 99)
        r = nv[keep] / ncd[keep]
        res.update(vel_ratio_p1=float(np.percentile(r, 1)), vel_ratio_median=float(np.median(r)),
                   vel_ratio_p99=float(np.percentile(r, 99)), vel_ratio_samples=int(r.size))
    return res


def resolution(prims, fps, every):
    """Is the hair's local motion resolved by ``fps / every`` frames per second? For a run written
    at ``fps``: the share of the non-root points' local velocity power (spectrum of the frame-to-frame
    differences over the run) above the coarse rate's Nyquist frequency and above twice it, the share
    of points with most of their power above it, and the velocity ratio (``measure``'s definition)
    at every ``every``-th frame against the central difference at the coarse rate and at ``fps``;
    and what the instantaneous velocity (the central difference at ``fps``, for a run written at
    every substep) scores against the coarse central difference: the ratio an exact velocity
    would measure at the coarse rate."""
    def ratio(v, cd):
        nv, ncd = np.linalg.norm(v, axis=2).ravel(), np.linalg.norm(cd, axis=2).ravel()
        keep = ncd >= 0.01 * np.percentile(ncd, 99)
        return np.percentile(nv[keep] / ncd[keep], [1, 99]).tolist()

    nyquist = fps / every / 2
    power, share, coarse, fine, exact = [], [], [], [], []
    for d in prims:
        first, _ = roots_tips(d["authored"], d["counts"])
        nonroot = np.ones(len(d["authored"]), dtype=bool)
        nonroot[first] = False
        x, v = d["local"][:, nonroot], d["vel"][:, nonroot]
        rate = np.diff(x, axis=0) * fps
        spec = (np.abs(np.fft.rfft(rate - rate.mean(axis=0), axis=0)) ** 2).sum(axis=2)   # (freq, points)
        freq = np.fft.rfftfreq(rate.shape[0], 1.0 / fps)
        power.append([spec.sum(), spec[freq > nyquist].sum(), spec[freq > 2 * nyquist].sum()])
        share.append(spec[freq > nyquist].sum(axis=0) > 0.5 * spec.sum(axis=0))
        centre = np.arange(every, x.shape[0] - every, every)            # frames with a coarse neighbour each side
        coarse.append((v[centre], (x[centre + every] - x[centre - every]) * (fps / every) / 2))
        fine.append((v[centre], (x[centre + 1] - x[centre - 1]) * fps / 2))
        exact.append((fine[-1][1], coarse[-1][1]))
    total, above, above2 = np.sum(power, axis=0)
    join = lambda pairs: ratio(np.concatenate([p[0] for p in pairs], axis=1),  # noqa: E731
                               np.concatenate([p[1] for p in pairs], axis=1))
    return dict(resolution_every=every, coarse_fps=fps / every,
                power_above_nyquist=float(above / total), power_above_2nyquist=float(above2 / total),
                points_mostly_above_nyquist=float(np.concatenate(share).mean()),
                vel_ratio_coarse_p1_p99=join(coarse), vel_ratio_fine_p1_p99=join(fine),
                instantaneous_vs_coarse_p1_p99=join(exact))


# ----------------------------------------------------------------------------- contact sheet

def render_view(out_usd, folder, width):
    """A stage over the simulation output that draws every strand ``width`` wide (80 um hair is
    below a pixel at contact-sheet sizes); only for the picture."""
    from pxr import Sdf, Usd, UsdGeom, Vt
    path = os.path.join(folder, "view.usda")
    stage = Usd.Stage.CreateNew(path)
    stage.GetRootLayer().subLayerPaths.append(os.path.abspath(out_usd))
    src = Usd.Stage.Open(out_usd)
    for k in ("upAxis", "metersPerUnit", "timeCodesPerSecond", "startTimeCode", "endTimeCode", "defaultPrim"):
        if src.HasAuthoredMetadata(k):
            stage.SetMetadata(k, src.GetMetadata(k))
    for prim in src.Traverse():
        if prim.IsA(UsdGeom.BasisCurves):
            c = UsdGeom.BasisCurves(stage.OverridePrim(prim.GetPath()))
            c.CreateWidthsAttr(Vt.FloatArray([width]))
            c.SetWidthsInterpolation(UsdGeom.Tokens.constant)
            pv = UsdGeom.PrimvarsAPI(c.GetPrim()).GetPrimvar("widths")
            if pv and pv.HasAuthoredValue():
                pv.Set(Vt.FloatArray([width]))
                pv.SetInterpolation(UsdGeom.Tokens.constant)
    stage.GetRootLayer().Save()
    return path


def contact_sheet(out_usd, folder, first, last, sheet, device, label, size=400, spp=4, width=None):
    from PIL import Image, ImageDraw
    if width:
        out_usd = render_view(out_usd, folder, width)
    frames_pat = os.path.join(folder, "frames", "f.####.png")
    cmd = dftl_warp_cmd() + ["render", out_usd, "--start", str(first), "--end", str(last),
                             "--step", str(max(last - first, 1)), "--resolution", f"{size}x{size}",
                             "--spp", str(spp), "--device", device, "-q", "-o", frames_pat]
    print("+", " ".join(cmd), flush=True)
    subprocess.run(cmd, check=True)
    imgs = []
    for f in (first, last):
        im = Image.open(os.path.join(folder, "frames", f"f.{f:04d}.png")).convert("RGBA")
        bg = Image.new("RGBA", im.size, (235, 235, 235, 255))
        imgs.append(Image.alpha_composite(bg, im).convert("RGB"))
    W = imgs[0].width + imgs[1].width
    H = max(i.height for i in imgs) + 22
    out = Image.new("RGB", (W, H), (255, 255, 255))
    draw = ImageDraw.Draw(out)
    for k, (im, f) in enumerate(zip(imgs, (first, last))):
        out.paste(im, (k * imgs[0].width, 22))
        draw.text((k * imgs[0].width + 6, 5), f"{label}  frame {f}", fill=(0, 0, 0))
    if out.width > 800:
        out = out.resize((800, round(out.height * 800 / out.width)), Image.LANCZOS)
    os.makedirs(os.path.dirname(os.path.abspath(sheet)) or ".", exist_ok=True)
    out.save(sheet, optimize=True)
    if os.path.getsize(sheet) > 150_000:
        out.quantize(colors=96).save(sheet, optimize=True)
    return sheet


# ----------------------------------------------------------------------------- main

def fmt(x, pct=False):
    if x is None:
        return "-"
    return f"{100 * x:.1f}%" if pct else f"{x:.3g}"


def markdown_row(label, r):
    return (f"| {label} | {r['strands']} | {fmt(r['tip_disp_median'])} | {fmt(r['tip_disp_p90'])} | "
            f"{fmt(r['curl_ratio_median'])} | {fmt(r['crest_up_start'], True)} -> {fmt(r['crest_up_end'], True)} | "
            f"{fmt(r['jitter_ratio'])} | {fmt(r.get('vel_ratio_p1'))} / {fmt(r.get('vel_ratio_p99'))} | "
            f"{r['sim_seconds']:.1f} |")


MD_HEADER = ("| run | strands | tip disp. median (L) | tip disp. p90 (L) | curl radius end/start (median) | "
             "tips above roots start -> end | jitter ratio | velocity ratio p1 / p99 | simulate s |\n"
             "|---|---|---|---|---|---|---|---|---|")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 epilog="Unknown flags are passed to `dftl-warp simulate`.")
    ap.add_argument("groom", help="groom stage (.usda/.usdc/.usd) with BasisCurves under its default prim")
    ap.add_argument("--head", default="auto",
                    help="auto (the groom's own colliders, if any), none, sphere (fitted to the roots) or a "
                         "head mesh .obj/.ply in the groom's units and axes")
    ap.add_argument("--head-x-up", action="store_true",
                    help="rotate the --head mesh as `dftl-warp import --up-axis X` rotates the hair")
    ap.add_argument("--motion", choices=("static", "turn"), default="static")
    ap.add_argument("--turn-degrees", type=float, default=60.0)
    ap.add_argument("--turn-period", type=float, default=2.0, help="seconds (default 2)")
    ap.add_argument("--frames", type=int, default=48, help="frames simulated, from 1 (default 48 = 2 s at 24 fps)")
    ap.add_argument("--resolution-every", type=int, default=0, metavar="K",
                    help="also measure whether fps/K frames per second resolve the hair's local motion "
                         "(spectrum, ratio at every K-th frame against the coarse and the full-rate central "
                         "difference; docs/grooms.md), e.g. 4 with --fps 96")
    ap.add_argument("--fps", type=float, default=None,
                    help="the wrapper's timeCodesPerSecond (default: the groom's); e.g. 96 with --frames 192 "
                         "--substeps 2 for the same 2 s and substep as 24 fps x 8, sampled 4x as often")
    ap.add_argument("--device", default="cpu", help="for simulate and render (default cpu)")
    ap.add_argument("--label", default=None, help="row label (default: groom file name + settings)")
    ap.add_argument("--json", default=None)
    ap.add_argument("--markdown", default=None, help="append a table row (header when the file is new)")
    ap.add_argument("--sheet", default=None, help="before/after PNG (frame 1 | last frame)")
    ap.add_argument("--sheet-size", type=int, default=400, help="pixels per panel (square)")
    ap.add_argument("--true-widths", action="store_true",
                    help="render the authored widths (default: every strand 1/300 of the groom's size, "
                         "as 80 um hair vanishes at 400 px)")
    ap.add_argument("--keep", default=None, help="keep the wrapper, output and frames in this folder")
    args, extra = ap.parse_known_args(argv)

    label = args.label or (os.path.splitext(os.path.basename(args.groom))[0] + f" {args.motion}"
                           + (" " + " ".join(extra) if extra else ""))
    folder = args.keep or tempfile.mkdtemp(prefix="groom_style_")
    os.makedirs(folder, exist_ok=True)
    try:
        wrapper, meta = write_wrapper(args.groom, folder, args)
        out_usd = os.path.join(folder, "out.usdc")
        cmd = dftl_warp_cmd() + ["simulate", wrapper, "-o", out_usd, "--device", args.device, "--quiet"] + extra
        print("+", " ".join(cmd), flush=True)
        t0 = time.perf_counter()
        subprocess.run(cmd, check=True)
        sim_s = time.perf_counter() - t0
        prims = read_output(out_usd, meta["start"], meta["end"])
        up_index = 2 if meta["up"] == "Z" else 1
        res = measure(prims, up_index, meta["fps"])
        if args.resolution_every:
            res.update(resolution(prims, meta["fps"], args.resolution_every))
        res.update(label=label, groom=os.path.abspath(args.groom), motion=args.motion, head=meta["head"],
                   frames=args.frames, device=args.device,
                   simulate_flags=extra, sim_seconds=sim_s, command=" ".join(sys.argv if argv is None else argv))
        if args.sheet:
            contact_sheet(out_usd, folder, meta["start"], meta["end"], args.sheet, args.device, label,
                          size=args.sheet_size, width=None if args.true_widths else meta["view_width"])
            res["sheet"] = args.sheet
        row = markdown_row(label, res)
        print(json.dumps(res, indent=2))
        print(MD_HEADER)
        print(row)
        if args.json:
            with open(args.json, "w") as fh:
                json.dump(res, fh, indent=2)
        if args.markdown:
            new = not os.path.exists(args.markdown)
            with open(args.markdown, "a") as fh:
                if new:
                    fh.write(MD_HEADER + "\n")
                fh.write(row + "\n")
        return 0
    finally:
        if not args.keep:
            shutil.rmtree(folder, ignore_errors=True)


if __name__ == "__main__":
    sys.exit(main())
