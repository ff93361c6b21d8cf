"""Reading what to render from a USD stage at one time code: the renderer's only USD reader.

- ``UsdGeom.BasisCurves``: ``points``, ``curveVertexCounts``, ``widths`` (or
  ``primvars:widths``) and ``primvars:displayColor`` with any interpolation (constant,
  uniform, varying, vertex, faceVarying; indexed primvars are flattened). Linear curves are
  drawn as they are; cubic ones (bezier, bspline, catmullRom; nonperiodic, periodic, pinned)
  are evaluated into ``CUBIC_STEPS`` linear pieces per span. Everything is moved to world
  space by the prim's local-to-world transform (widths are scaled by its mean scale). The
  render curves of a guide binding cache (``simulate --guides-output binding``) are deformed by
  their guides at the time rendered (:mod:`.binding`).
- ``UsdGeom.Sphere``, ``Capsule``, ``Cube`` (analytic, with their transforms) and ``Mesh``
  (triangulated, world space, the faces of ``holeIndices`` left out), drawn in a neutral material.
- ``UsdGeom.Camera`` prims (:func:`read_camera`).

Invisible prims and prims of purpose ``guide`` or ``proxy`` are skipped. Visible prims of other
types (NurbsCurves, Cylinder, Cone, ...) are not drawn, and curves without widths are drawn at a
default width: :func:`render_notes` says so. Bad data (and a value of the wrong type:
:mod:`.usd_checks`) raises :class:`~dftl_warp.errors.UserError` naming the file, the prim and the
attribute or index.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..core.layout import strand_offsets
from ..checks import check_lengths
from ..errors import UserError
from ..usd import curves as curve_checks
from ..usd.scene import transform_points
from . import binding, usd_checks
from .camera import Camera
from .scene import BOX, CAPSULE, SPHERE, RenderScene, Shape, default_width, root_to_tip, strand_colors

#: linear pieces per cubic span
CUBIC_STEPS = 6

_BASIS = {  # (4x4 basis matrix for [1, u, u^2, u^3] @ M @ [P0..P3], vstep)
    "bezier": (np.array([[1, 0, 0, 0], [-3, 3, 0, 0], [3, -6, 3, 0], [-1, 3, -3, 1]], float), 3),
    "bspline": (np.array([[1, 4, 1, 0], [-3, 0, 3, 0], [3, -6, 3, 0], [-1, 3, -3, 1]], float) / 6.0, 1),
    "catmullRom": (np.array([[0, 2, 0, 0], [-1, 0, 1, 0], [2, -5, 4, -1], [-1, 3, -3, 1]], float) / 2.0, 1),
}


def open_stage(path, warnings: list | None = None):
    """Open a USD stage for reading, or raise UserError, as the simulation's reader does
    (:func:`dftl_warp.usd.read.open_stage`: the same one-line messages); also when a sublayer
    of it cannot be found (e.g. a simulated output whose input has moved: it would render
    nothing). Warnings USD posts while composing are appended to ``warnings`` (one line each)."""
    from ..usd.read import open_stage as read_open_stage

    stage, found = read_open_stage(path)
    _check_sublayers(stage, path)
    if warnings is not None:
        warnings.extend(found)
    return stage


def _check_sublayers(stage, source) -> None:
    """UserError naming the first sublayer of the stage's layer stack that did not open."""
    opened = set()
    for layer in stage.GetLayerStack(includeSessionLayers=False):
        opened.update(x for x in (layer.identifier, layer.realPath) if x)
    for layer in stage.GetLayerStack(includeSessionLayers=False):
        for sub in layer.subLayerPaths:
            absolute = layer.ComputeAbsolutePath(sub)
            if absolute not in opened and str(Path(absolute).resolve()) not in opened:
                raise UserError(f"{source}: sublayer {sub} of {layer.identifier} cannot be opened "
                                f"({absolute}: missing or unreadable; was the input moved?)")


def check_samples(stage, times, source: str | None = None) -> None:
    """UserError naming the first of ``times`` at which a time-sampled BasisCurves ``points``
    has no sample of its own (before its first or after its last): USD would hold the nearest
    sample and every such frame would show the same hair. Stages without time-sampled points
    (a static groom, perhaps on an animated transform) pass."""
    from pxr import Usd, UsdGeom

    source = source or stage_source(stage)
    ranges = []  # (first, last, prim path)
    for prim in Usd.PrimRange.Stage(stage, Usd.TraverseInstanceProxies(Usd.PrimDefaultPredicate)):
        if prim.IsA(UsdGeom.BasisCurves):
            samples = UsdGeom.BasisCurves(prim).GetPointsAttr().GetTimeSamples()
            if samples:
                ranges.append((samples[0], samples[-1], str(prim.GetPath())))
    if not ranges:
        return
    for t in times:
        if t is None:
            continue
        for first, last, path in ranges:
            if not first - 1e-6 <= t <= last + 1e-6:
                raise UserError(f"{source}: frame {t:g} has no samples: {path}.points has samples at "
                                f"{first:g}..{last:g} only (render those frames, or simulate this one)")


def is_empty(scene) -> bool:
    """True when a RenderScene draws nothing (no strand segment, shape or mesh triangle): curves of
    one vertex each have no segment to draw (they rendered an empty image without a word)."""
    return scene.is_empty()


def render_notes(stage, source: str | None = None) -> list:
    """Warnings (one line each) about what the renderer leaves out or approximates: curves of fewer
    than 2 vertices (no segment to draw), visible prims of types it does not draw (NurbsCurves,
    Cylinder, Cone, ...: one line for all), BasisCurves drawn at the default width (no widths: one
    line for all) and Mesh prims without faces."""
    from pxr import UsdGeom

    source = source or stage_source(stage)
    time = default_time(stage)
    notes, skipped, widthless, faceless = [], {}, [], []
    for prim in _drawn_prims(stage, time):
        if prim.IsA(UsdGeom.Mesh):
            m = UsdGeom.Mesh(prim)
            if _faceless(m.GetPointsAttr().Get(time), m.GetFaceVertexCountsAttr().Get(time),
                         m.GetFaceVertexIndicesAttr().Get(time)):
                faceless.append(str(prim.GetPath()))
        elif prim.IsA(UsdGeom.Gprim) and str(prim.GetTypeName()) not in usd_checks.DRAWN_TYPES:
            skipped.setdefault(str(prim.GetTypeName()), []).append(str(prim.GetPath()))
        if not prim.IsA(UsdGeom.BasisCurves):
            continue
        if not _has_widths(prim, time):
            widthless.append(str(prim.GetPath()))
        counts = curve_checks.vertex_counts(UsdGeom.BasisCurves(prim).GetCurveVertexCountsAttr().Get(time),
                                            f"{source}: {prim.GetPath()}")
        short = np.flatnonzero((counts >= 0) & (counts < 2))
        if len(short):
            notes.append(f"{source}: {prim.GetPath()}: {len(short)} of {len(counts)} curves have fewer than 2 "
                         f"vertices (curveVertexCounts[{short[0]}] = {counts[short[0]]}): not drawn (no segment)")
    if faceless:
        notes.append(f"{source}: {usd_checks.listed(faceless, 'Mesh prim')} without faces (no points, "
                     f"faceVertexCounts or faceVertexIndices): not drawn")
    return notes + [n for n in (usd_checks.skipped_note(source, skipped), usd_checks.widthless_note(source, widthless))
                    if n]


def _faceless(points, counts, indices) -> bool:
    """True for a Mesh with nothing to draw: no points, face counts or indices."""
    return points is None or counts is None or indices is None or np.size(counts) == 0


def _has_widths(prim, time) -> bool:
    """Whether a BasisCurves prim has widths the renderer draws (``primvars:widths`` or a
    non-empty ``widths``), as :func:`_read_curves` reads them."""
    from pxr import UsdGeom

    pv = UsdGeom.PrimvarsAPI(prim).GetPrimvar("widths")
    if pv and pv.HasAuthoredValue() and pv.Get(time) is not None:
        return True
    w = UsdGeom.BasisCurves(prim).GetWidthsAttr().Get(time)
    return w is not None and np.size(w) > 0


def stage_source(stage) -> str:
    layer = stage.GetRootLayer()
    return layer.realPath or layer.identifier


def up_axis(stage) -> str:
    """The stage's up axis, ``"Y"`` or ``"Z"``; any other token is a UserError naming the file, as
    the simulation's reader refuses it."""
    from pxr import UsdGeom

    axis = str(UsdGeom.GetStageUpAxis(stage))
    if axis.upper() not in ("Y", "Z"):
        raise UserError(f"{stage_source(stage)}: upAxis = {axis!r}: must be \"Y\" or \"Z\"")
    return axis.upper()


def time_range(stage):
    """(start, end) time codes authored on the stage, or None."""
    if stage.HasAuthoredTimeCodeRange():
        return float(stage.GetStartTimeCode()), float(stage.GetEndTimeCode())
    return None


def default_time(stage):
    """The stage's start time code if it has one, else the default time."""
    from pxr import Usd

    r = time_range(stage)
    return Usd.TimeCode(r[0]) if r else Usd.TimeCode.Default()


def _time(t):
    from pxr import Usd

    if t is None:
        return Usd.TimeCode.Default()
    if isinstance(t, Usd.TimeCode):
        return t
    return Usd.TimeCode(float(t))


def _drawn_prims(stage, time):
    from pxr import Usd, UsdGeom

    it = iter(Usd.PrimRange.Stage(stage, Usd.TraverseInstanceProxies(Usd.PrimDefaultPredicate)))
    for prim in it:
        img = UsdGeom.Imageable(prim)
        if not img:
            continue
        if img.ComputeVisibility(time) == UsdGeom.Tokens.invisible or str(img.ComputePurpose()) in ("guide", "proxy"):
            it.PruneChildren()
            continue
        yield prim


def _world(prim, time) -> np.ndarray:
    """Local-to-world transform of ``prim`` at ``time`` as USD gives it: a 4x4 matrix for row
    vectors, the convention of :func:`dftl_warp.usd.scene.transform_points` (the tracer's shapes
    and cameras take its transpose, for column vectors)."""
    from pxr import UsdGeom

    return np.array(UsdGeom.Xformable(prim).ComputeLocalToWorldTransform(time), dtype=np.float64)


def _finite(values, source, prim, name):
    bad = ~np.isfinite(values.reshape(len(values), -1)).all(axis=1)
    if bad.any():
        raise UserError(f"{source}: {prim.GetPath()}: {name}[{int(np.argmax(bad))}] is not finite")


def read_render_scene(stage, time=None, source: str | None = None) -> RenderScene:
    """Everything drawn at ``time`` (a number, a Usd.TimeCode or None = default). Data USD
    itself refuses (a bad xformOp, a value of the wrong type) is a UserError too."""
    from pxr import Tf

    source = source or stage_source(stage)
    try:
        return _read_render_scene(stage, time, source)
    except Tf.ErrorException as exc:
        raise UserError(f"{source}: {_usd_message(exc)}") from None


#: the authored size attribute of each analytic shape, and the factor from the shape's first parameter
_SIZE = {SPHERE: ("radius", 1.0), CAPSULE: ("radius", 1.0), BOX: ("size", 2.0)}


def _check_float32(shape, source) -> None:
    """UserError naming the prim and attribute where a shape's size or position, in world space, is
    beyond what the float32 ray tracer squares (:data:`~dftl_warp.checks.MAX_LENGTH`): before,
    a Sphere of radius 1e300 rendered with numpy's overflow warning."""
    name, factor = _SIZE[shape.kind]
    where = f"{source}: {shape.path}"
    linear = shape.world_from_local[:3, :3]
    stretch = max(float(np.linalg.norm(linear, axis=0).max()), 1.0)
    check_lengths([factor * shape.params[0] * stretch], name, where, indexed=False,
                  world=" in world space" if stretch > 1.0 else "")
    if shape.kind == CAPSULE:
        check_lengths([2.0 * shape.params[1] * stretch], "height", where, indexed=False)
    check_lengths([shape.world_from_local[:3, 3]], "its position", where, indexed=False,
                  world=" in world space")


def _usd_message(exc) -> str:
    """The last line of a USD error, without its 'Error in ... at line ... in file ...' prefix."""
    import re

    lines = [x.strip() for x in str(exc).strip().splitlines() if x.strip()]
    text = lines[-1] if lines else type(exc).__name__
    return re.sub(r"^Error in '.*?' at line \d+ in file \S+ : ", "", text).strip("'")


def _read_render_scene(stage, time, source) -> RenderScene:
    from pxr import UsdGeom

    time = _time(time)
    strands = []  # (points, counts, radii, colors)
    shapes = []
    mesh_pts, mesh_tris = [], []
    n_mesh = 0
    for prim in _drawn_prims(stage, time):
        where = f"{source}: {prim.GetPath()}"   # a size of the wrong type ("big") is one line (usd_checks.number)
        if prim.IsA(UsdGeom.BasisCurves):
            s = _read_curves(prim, time, source)
            if s is not None:
                strands.append(s)
        elif prim.IsA(UsdGeom.Sphere):
            r = usd_checks.number(UsdGeom.Sphere(prim).GetRadiusAttr().Get(time), "radius", where)
            shapes.append(Shape(SPHERE, _world(prim, time).T, (r, 0.0, 0.0), str(prim.GetPath())))
        elif prim.IsA(UsdGeom.Capsule):
            c = UsdGeom.Capsule(prim)
            axis = usd_checks.capsule_axis(c.GetAxisAttr().Get(time), where)
            shapes.append(Shape(CAPSULE, _world(prim, time).T,
                                (usd_checks.number(c.GetRadiusAttr().Get(time), "radius", where),
                                 0.5 * usd_checks.number(c.GetHeightAttr().Get(time), "height", where), float(axis)),
                                str(prim.GetPath())))
        elif prim.IsA(UsdGeom.Cube):
            size = usd_checks.number(UsdGeom.Cube(prim).GetSizeAttr().Get(time), "size", where)
            shapes.append(Shape(BOX, _world(prim, time).T, (0.5 * size,) * 3, str(prim.GetPath())))
        elif prim.IsA(UsdGeom.Mesh):
            m = _read_mesh(prim, time, source)
            if m is not None:
                mesh_pts.append(m[0])
                mesh_tris.append(m[1] + n_mesh)
                n_mesh += len(m[0])
    scene = RenderScene(shapes=shapes, up_axis=up_axis(stage))
    for s in shapes:
        if not np.isfinite(s.world_from_local).all() or not np.isfinite(s.params).all() or s.params[0] < 0:
            raise UserError(f"{source}: {s.path}: transform or size is not a finite, non-negative value")
        _check_float32(s, source)
    if strands:
        scene.points = np.concatenate([s[0] for s in strands])
        scene.curve_vertex_counts = np.concatenate([s[1] for s in strands])
        scene.radii = np.concatenate([s[2] for s in strands])
        scene.colors = np.concatenate([s[3] for s in strands])
    if mesh_pts:
        scene.mesh_points = np.concatenate(mesh_pts)
        scene.mesh_triangles = np.concatenate(mesh_tris)
    return scene


def _primvar(prim, name, time, where: str = ""):
    """(values, interpolation) of primvar ``name`` (flattened), or (None, None)."""
    from pxr import UsdGeom

    pv = UsdGeom.PrimvarsAPI(prim).GetPrimvar(name)
    if not pv or not pv.HasAuthoredValue():
        return None, None
    where = where or str(prim.GetPath())
    v = curve_checks.flattened(pv, time, where)
    if v is None:
        return None, None
    name = pv.GetAttr().GetName()
    v = curve_checks.colors(v, name, where) if name == "primvars:displayColor" else curve_checks.numbers(v, name, where)
    return v, str(pv.GetInterpolation())


def _expected(interp, n_curves, n_vertices, n_varying):
    return {"constant": 1, "uniform": n_curves, "varying": n_varying,
            "faceVarying": n_varying, "vertex": n_vertices}.get(interp)


def _read_curves(prim, time, source):
    from pxr import UsdGeom

    curves = UsdGeom.BasisCurves(prim)
    path = prim.GetPath()
    pts = curves.GetPointsAttr().Get(time)
    # the simulation reader's checks: a scalar, strings or fractions are one line, not a crash or a truncation
    counts = curve_checks.vertex_counts(curves.GetCurveVertexCountsAttr().Get(time), f"{source}: {path}")
    if pts is None or len(counts) == 0:
        return None
    pts = np.asarray(pts, dtype=np.float64).reshape(-1, 3)
    if (counts < 0).any():
        raise UserError(f"{source}: {path}: curveVertexCounts[{int(np.argmax(counts < 0))}] is negative")
    if counts.sum() != len(pts):
        raise UserError(f"{source}: {path}: points has {len(pts)} entries but curveVertexCounts sums to {int(counts.sum())}")
    _finite(pts, source, prim, "points")
    if binding.is_bound(prim):   # a guide binding cache: the curves follow their guides
        pts = binding.deformed_points(prim, pts, counts, time, source)
    curve_type = str(curves.GetTypeAttr().Get(time) or "cubic")
    basis = str(curves.GetBasisAttr().Get(time) or "bezier")
    wrap = str(curves.GetWrapAttr().Get(time) or "nonperiodic")
    if curve_type not in ("linear", "cubic"):
        raise UserError(f"{source}: {path}: unknown curve type {curve_type!r}")
    if curve_type == "cubic" and basis not in _BASIS:
        raise UserError(f"{source}: {path}: unsupported cubic basis {basis!r} (bezier, bspline, catmullRom)")
    if wrap not in ("nonperiodic", "periodic", "pinned"):
        raise UserError(f"{source}: {path}: unknown wrap {wrap!r}")
    # the simulation reader's rule: a cubic curve needs the control points its basis uses
    curve_checks.check_vertex_counts(counts, curve_type, basis, wrap, f"{source}: {path}")
    spans = curve_checks.curve_spans(counts, curve_type, basis, wrap)
    n_varying = int((spans + (0 if wrap == "periodic" else 1)).sum()) if curve_type == "cubic" else len(pts)

    def per_vertex(values, interp, name, width):
        """Expand a primvar to (values per control point, values per varying point or None)."""
        values = values.reshape(-1, width)
        expected = _expected(interp, len(counts), len(pts), n_varying)
        if expected is None:
            raise UserError(f"{source}: {path}: {name}: unknown interpolation {interp!r}")
        if len(values) != expected:
            raise UserError(f"{source}: {path}: {name}: {len(values)} values for {interp!r} interpolation, expected {expected}")
        _finite(values, source, prim, name)
        if interp == "constant":
            return np.repeat(values, len(pts), axis=0), None
        if interp == "uniform":
            return np.repeat(values, counts, axis=0), None
        if interp in ("varying", "faceVarying") and curve_type == "cubic":
            return None, values
        return values, None

    # widths: primvars:widths wins over the widths attribute
    widths, w_interp = _primvar(prim, "widths", time, f"{source}: {path}")
    if widths is None:
        w = curves.GetWidthsAttr().Get(time)
        w = None if w is None else curve_checks.numbers(w, "widths", f"{source}: {path}")  # a scalar: one value
        if w is not None and len(w):
            widths, w_interp = w, str(curves.GetWidthsInterpolation())
    if widths is None:
        w_v, w_var = np.full((len(pts), 1), default_width(pts)), None
    else:
        w_v, w_var = per_vertex(widths, w_interp, "widths", 1)
        if (widths < 0).any():
            raise UserError(f"{source}: {path}: widths[{int(np.argmax(widths < 0))}] is negative")

    colors, c_interp = _primvar(prim, "displayColor", time, f"{source}: {path}")
    c_v = c_var = None
    ramp = colors is None or c_interp in ("constant", "uniform")
    if colors is not None:
        c_v, c_var = per_vertex(colors, c_interp, "primvars:displayColor", 3)

    world = _world(prim, time)
    if curve_type == "linear":
        out_pts, out_counts, out_w, out_c = _linear(pts, counts, wrap, w_v, c_v)
    else:
        out_pts, out_counts, out_w, out_c = _cubic(pts, counts, basis, wrap, spans, w_v, w_var, c_v, c_var)
    out_pts = transform_points(world, out_pts)
    scale = abs(np.linalg.det(world[:3, :3])) ** (1.0 / 3.0)
    radii = 0.5 * out_w.reshape(-1) * scale
    if ramp:
        base = None if colors is None else out_c.reshape(-1, 3)
        if base is None:
            cols = strand_colors(out_counts, None)
        else:
            u = root_to_tip(out_counts)[:, None]
            from .scene import ROOT_DARKENING

            cols = base * (ROOT_DARKENING + (1.0 - ROOT_DARKENING) * u)
    else:
        cols = out_c.reshape(-1, 3)
    return out_pts, out_counts, radii, np.clip(cols, 0.0, None)


def _linear(pts, counts, wrap, w_v, c_v):
    if wrap != "periodic":
        return pts, counts, w_v, (c_v if c_v is not None else np.zeros((len(pts), 3)))
    # close every loop by repeating its first vertex
    starts = strand_offsets(counts)
    idx = np.concatenate([np.r_[np.arange(s, s + n), s] if n > 0 else np.zeros(0, int) for s, n in zip(starts, counts)])
    c = c_v if c_v is not None else np.zeros((len(pts), 3))
    return pts[idx], np.where(counts > 0, counts + 1, 0), w_v[idx], c[idx]


def _cubic(pts, counts, basis, wrap, spans, w_v, w_var, c_v, c_var):
    """Evaluate cubic curves into linear pieces; vertex primvars follow the basis, varying ones
    are linear per span."""
    m, vstep = _BASIS[basis]
    u = np.linspace(0.0, 1.0, CUBIC_STEPS + 1)
    weights = np.stack([np.ones_like(u), u, u * u, u * u * u], axis=1) @ m  # (steps+1, 4)
    starts = strand_offsets(counts)
    var_starts = np.cumsum(spans + (0 if wrap == "periodic" else 1)) - (spans + (0 if wrap == "periodic" else 1))
    vertex_data = [pts]
    if w_v is not None:
        vertex_data.append(w_v)
    if c_v is not None:
        vertex_data.append(c_v)
    stacked = np.concatenate(vertex_data, axis=1)
    out, out_counts, out_var_w, out_var_c = [], [], [], []
    for k, (s, n, ns) in enumerate(zip(starts, counts, spans)):
        if ns <= 0:
            out_counts.append(0)
            continue
        cv = stacked[s:s + n]
        if wrap == "pinned" and basis != "bezier":
            cv = np.concatenate([2 * cv[:1] - cv[1:2], cv, 2 * cv[-1:] - cv[-2:-1]])
        elif wrap == "periodic":
            cv = np.concatenate([cv, cv[:3]])
        idx = (np.arange(ns)[:, None] * vstep + np.arange(4)[None, :])  # (ns, 4)
        pieces = np.einsum("uk,skd->sud", weights, cv[idx])  # (ns, steps+1, d)
        curve = np.concatenate([pieces[0]] + [p[1:] for p in pieces[1:]])
        out.append(curve)
        out_counts.append(len(curve))
        t = np.concatenate([[0.0], (np.arange(ns)[:, None] + u[None, 1:]).reshape(-1)])  # span param
        for var, dst in ((w_var, out_var_w), (c_var, out_var_c)):
            if var is not None:
                vv = var[var_starts[k]:var_starts[k] + ns + (0 if wrap == "periodic" else 1)]
                if wrap == "periodic":
                    vv = np.concatenate([vv, vv[:1]])
                dst.append(np.stack([np.interp(t, np.arange(len(vv)), vv[:, j]) for j in range(vv.shape[1])], axis=1))
    out_counts = np.asarray(out_counts, dtype=np.int64)
    if not out:
        return np.zeros((0, 3)), out_counts, np.zeros((0, 1)), np.zeros((0, 3))
    allv = np.concatenate(out)
    col = 3
    if w_v is not None:
        widths = allv[:, col:col + 1]
        col += 1
    else:
        widths = np.concatenate(out_var_w)
    if c_v is not None:
        colors = allv[:, col:col + 3]
    elif out_var_c:
        colors = np.concatenate(out_var_c)
    else:
        colors = np.zeros((len(allv), 3))
    return allv[:, :3], out_counts, np.maximum(widths, 0.0), colors


def _read_mesh(prim, time, source):
    from pxr import UsdGeom

    mesh = UsdGeom.Mesh(prim)
    pts = mesh.GetPointsAttr().Get(time)
    fvc = mesh.GetFaceVertexCountsAttr().Get(time)
    fvi = mesh.GetFaceVertexIndicesAttr().Get(time)
    if _faceless(pts, fvc, fvi):   # said once by render_notes
        return None
    # faces of < 3 vertices and bad holeIndices are refused as the simulation refuses them; holes are not drawn
    pts, tris = usd_checks.mesh_faces(pts, fvc, fvi, mesh.GetHoleIndicesAttr().Get(time), f"{source}: {prim.GetPath()}")
    world = _world(prim, time)
    return transform_points(world, pts), tris


def cameras(stage):
    """Paths of the UsdGeom.Camera prims on the stage, in traversal order."""
    from pxr import UsdGeom

    return [str(p.GetPath()) for p in stage.Traverse() if p.IsA(UsdGeom.Camera)]


def read_camera(stage, path, time=None, source: str | None = None) -> Camera:
    """The UsdGeom.Camera at ``path`` at ``time``."""
    from pxr import Tf

    source = source or stage_source(stage)
    try:
        return _read_camera(stage, path, time, source)
    except Tf.ErrorException as exc:
        raise UserError(f"{source}: {path}: {_usd_message(exc)}") from None


def _read_camera(stage, path, time, source) -> Camera:
    from pxr import Sdf, UsdGeom

    time = _time(time)
    prim = stage.GetPrimAtPath(Sdf.Path(path)) if Sdf.Path.IsValidPathString(path) else None
    if not prim or not prim.IsA(UsdGeom.Camera):
        found = cameras(stage)
        hint = f" (cameras: {', '.join(found[:5])})" if found else " (the stage has no camera)"
        raise UserError(f"{source}: {path}: no UsdGeom.Camera prim at this path{hint}")
    cam = UsdGeom.Camera(prim)

    where = f"{source}: {path}"

    def get(attr, default):   # a value of the wrong type ("50mm") is one line naming it
        return usd_checks.number(attr.Get(time), attr.GetName(), where, default)

    clip = cam.GetClippingRangeAttr().Get(time)
    if clip is not None and (isinstance(clip, str) or np.shape(clip) != (2,)):
        raise UserError(f"{where}: clippingRange = {usd_checks.shown(clip)}: expected two numbers (near, far)")
    near, far = (usd_checks.number(clip[0], "clippingRange[0]", where),
                 usd_checks.number(clip[1], "clippingRange[1]", where)) if clip is not None else (1.0, 1.0e6)
    projection = cam.GetProjectionAttr().Get(time) or "perspective"
    if not isinstance(projection, str) or projection not in ("perspective", "orthographic"):
        raise UserError(f"{where}: projection = {usd_checks.shown(projection)}: expected \"perspective\" or "
                        "\"orthographic\"")
    try:   # the camera's own checks (dftl_warp/render/camera.py), named with the file
        result = Camera(
            world_from_camera=_world(prim, time).T,
            focal_length=get(cam.GetFocalLengthAttr(), 50.0),
            horizontal_aperture=get(cam.GetHorizontalApertureAttr(), 20.955),
            vertical_aperture=get(cam.GetVerticalApertureAttr(), 15.2908),
            horizontal_aperture_offset=get(cam.GetHorizontalApertureOffsetAttr(), 0.0),
            vertical_aperture_offset=get(cam.GetVerticalApertureOffsetAttr(), 0.0),
            near=near, far=far,
            projection=str(projection),
            path=str(path),
        )
    except ValueError as exc:
        raise UserError(f"{source}: {exc}") from None
    if not (result.focal_length > 0 and result.horizontal_aperture > 0 and result.vertical_aperture > 0):
        raise UserError(f"{source}: {path}: focal length and apertures must be positive")
    if not (0 <= near < far) or not np.isfinite(result.world_from_camera).all():
        raise UserError(f"{source}: {path}: clippingRange {clip} or transform is invalid")
    axes = np.asarray(result.world_from_camera, dtype=np.float64)[:3, :3]
    if abs(np.linalg.det(axes)) <= 1e-12 * float(np.abs(axes).max()) ** 3:
        # a zero scale: the camera has no view direction (the image came out blank, with numpy's warning)
        raise UserError(f"{source}: {path}: the camera's transform is degenerate (a zero scale?): it has no view "
                        "direction")
    return result
