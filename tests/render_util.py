"""Helpers of the renderer tests: USD stages, and an independent expected coverage computed
with numpy through the camera's own Gf frustum (pxr), not through dftl_warp.render."""

import numpy as np
from pxr import Gf, Usd, UsdGeom, Vt


def new_stage(path=None, up="Y"):
    stage = Usd.Stage.CreateNew(str(path)) if path else Usd.Stage.CreateInMemory()
    UsdGeom.SetStageUpAxis(stage, up)
    return stage


def add_curves(stage, prim_path, strands, widths=None, interpolation="constant", colors=None,
               color_interpolation="vertex", time=None, curve_type="linear"):
    """BasisCurves from a list of (n_i, 3) arrays."""
    c = UsdGeom.BasisCurves.Get(stage, prim_path) or UsdGeom.BasisCurves.Define(stage, prim_path)
    c.CreateTypeAttr(curve_type)
    c.CreateCurveVertexCountsAttr(Vt.IntArray([len(s) for s in strands]))
    pts = np.concatenate(strands).astype(np.float32)
    t = Usd.TimeCode.Default() if time is None else Usd.TimeCode(time)
    c.GetPointsAttr().Set(Vt.Vec3fArray.FromNumpy(pts), t)
    if widths is not None:
        c.CreateWidthsAttr(Vt.FloatArray([float(w) for w in np.atleast_1d(widths)]))
        c.SetWidthsInterpolation(interpolation)
    if colors is not None:
        pv = UsdGeom.PrimvarsAPI(c.GetPrim()).CreatePrimvar(
            "displayColor", Sdf_type("Color3fArray"), color_interpolation)
        pv.Set(Vt.Vec3fArray.FromNumpy(np.asarray(colors, dtype=np.float32).reshape(-1, 3)))
    return c


def Sdf_type(name):
    from pxr import Sdf

    return getattr(Sdf.ValueTypeNames, name)


def add_camera(stage, path="/cam", translate=(0.0, 0.0, 1.0), rotate_xyz=(0.0, 0.0, 0.0), focal=50.0,
               aperture=(36.0, 24.0), offset=(0.0, 0.0), clipping=(0.01, 100.0), projection="perspective"):
    cam = UsdGeom.Camera.Define(stage, path)
    cam.AddTranslateOp().Set(Gf.Vec3d(*translate))
    cam.AddRotateXYZOp().Set(Gf.Vec3f(*rotate_xyz))
    cam.CreateFocalLengthAttr(focal)
    cam.CreateHorizontalApertureAttr(aperture[0])
    cam.CreateVerticalApertureAttr(aperture[1])
    cam.CreateHorizontalApertureOffsetAttr(offset[0])
    cam.CreateVerticalApertureOffsetAttr(offset[1])
    cam.CreateClippingRangeAttr(Gf.Vec2f(*clipping))
    cam.CreateProjectionAttr(projection)
    return cam


def gf_view_projection(stage, cam_path, width, height, policy="expandAperture", time=None):
    """World -> clip matrix (row vectors, as Gf) of the USD camera, its frustum window
    conformed to the image aspect by ``policy``."""
    t = Usd.TimeCode.Default() if time is None else Usd.TimeCode(time)
    frustum = UsdGeom.Camera(stage.GetPrimAtPath(cam_path)).GetCamera(t).frustum
    win = frustum.window
    (l, b), (r, tp) = win.min, win.max
    cx, cy, w, h = 0.5 * (l + r), 0.5 * (b + tp), r - l, tp - b
    image, aperture = width / height, w / h
    widen = {"expandAperture": image > aperture, "cropAperture": image < aperture,
             "adjustApertureWidth": True, "adjustApertureHeight": False}[policy]
    if widen:
        w = h * image
    else:
        h = w / image
    frustum.window = Gf.Range2d(Gf.Vec2d(cx - w / 2, cy - h / 2), Gf.Vec2d(cx + w / 2, cy + h / 2))
    return np.array(frustum.ComputeViewMatrix()) @ np.array(frustum.ComputeProjectionMatrix()), (w / width)


def pixel_rays(view_projection, width, height, sub=1):
    """Unit rays (origin on the near plane) through a ``sub`` x ``sub`` grid of points in every
    pixel: origins, directions of shape (height, width, sub*sub, 3)."""
    inv = np.linalg.inv(view_projection)
    k = (np.arange(sub) + 0.5) / sub
    px = (np.arange(width)[:, None] + k[None, :]).reshape(-1)
    py = (np.arange(height)[:, None] + k[None, :]).reshape(-1)
    X, Y = np.meshgrid(px, py)  # (H*sub, W*sub)
    ndc = np.stack([2 * X / width - 1, 1 - 2 * Y / height], axis=-1)

    def unproject(z):
        p = np.concatenate([ndc, np.full(ndc.shape[:2] + (1,), z), np.ones(ndc.shape[:2] + (1,))], axis=-1)
        q = p @ inv
        return q[..., :3] / q[..., 3:]

    o, f = unproject(-1.0), unproject(1.0)
    d = f - o
    d /= np.linalg.norm(d, axis=-1, keepdims=True)

    def group(a):
        return a.reshape(height, sub, width, sub, 3).transpose(0, 2, 1, 3, 4).reshape(height, width, sub * sub, 3)

    return group(o), group(d)


def ray_segment_distance(o, d, a, b):
    """Smallest distance between rays o + t d (t >= 0, |d| = 1) and the segment [a, b]; also
    the ray parameter where it is reached. o, d: (..., 3)."""
    e = b - a
    ee = float(e @ e)
    w = o - a
    de = d @ e
    dw = np.einsum("...k,...k->...", d, w)
    ew = w @ e
    best = np.full(o.shape[:-1], np.inf)
    best_t = np.zeros(o.shape[:-1])

    def consider(s, t):
        nonlocal best, best_t
        s = np.clip(s, 0.0, 1.0)
        t = np.maximum(t, 0.0)
        dist = np.linalg.norm(o + t[..., None] * d - (a + s[..., None] * e), axis=-1)
        better = dist < best
        best = np.where(better, dist, best)
        best_t = np.where(better, t, best_t)

    denom = ee - de * de
    with np.errstate(divide="ignore", invalid="ignore"):
        s_int = np.where(denom > 1e-18, (ew - de * dw) / np.where(denom > 1e-18, denom, 1.0), 0.0)
    t_int = s_int * de - dw
    inside = (s_int >= 0) & (s_int <= 1) & (t_int >= 0)
    consider(np.where(inside, s_int, 0.0), np.where(inside, t_int, -dw))
    for s in (0.0, 1.0):  # ends of the segment: t closest to that end
        consider(np.full(o.shape[:-1], s), s * de - dw)
    if ee > 0:  # t = 0: the ray origin against the segment
        consider(ew / ee, np.zeros(o.shape[:-1]))
    return best, best_t


def expected_tube_coverage(origins, dirs, strands, radii, near=0.0, far=np.inf):
    """Covered fraction per pixel of capsule chains: ``strands`` list of (n, 3), ``radii`` one
    radius per strand (or per strand an (n,) array: linear in between, approximated by
    sub-capsules). origins/dirs from :func:`pixel_rays`."""
    hit = np.zeros(origins.shape[:-1], dtype=bool)
    for pts, r in zip(strands, radii):
        r = np.broadcast_to(np.asarray(r, dtype=np.float64), (len(pts),))
        for i in range(len(pts) - 1):
            if r[i] == r[i + 1]:
                dist, t = ray_segment_distance(origins, dirs, pts[i], pts[i + 1])
                hit |= (dist <= r[i]) & (t >= near) & (t <= far)
                continue
            # a tapered piece: sub-capsules, tested only on the rays near the whole segment
            dist, _ = ray_segment_distance(origins, dirs, pts[i], pts[i + 1])
            near_rays = dist <= max(r[i], r[i + 1])
            o, d = origins[near_rays], dirs[near_rays]
            sub_hit = np.zeros(len(o), dtype=bool)
            pieces = 64
            for k in range(pieces):
                u0, u1 = k / pieces, (k + 1) / pieces
                a = pts[i] + u0 * (pts[i + 1] - pts[i])
                b = pts[i] + u1 * (pts[i + 1] - pts[i])
                rad = r[i] + 0.5 * (u0 + u1) * (r[i + 1] - r[i])
                dist, t = ray_segment_distance(o, d, a, b)
                sub_hit |= (dist <= rad) & (t >= near) & (t <= far)
            hit[near_rays] |= sub_hit
    return hit.mean(axis=-1)


def alpha_centroid(alpha):
    ys, xs = np.mgrid[0:alpha.shape[0], 0:alpha.shape[1]]
    w = alpha.sum()
    return (xs * alpha).sum() / w + 0.5, (ys * alpha).sum() / w + 0.5
