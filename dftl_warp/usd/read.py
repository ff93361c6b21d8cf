"""The one module that reads USD for simulation: a stage -> :class:`~dftl_warp.usd.scene.Scene`.

Rules (``docs/usd.md`` is the user-facing version):

- hair is every ``UsdGeom.BasisCurves`` prim (or those at/below the ``prims`` selection); vertex 0
  of each curve is its root; cubic curves contribute their control points; periodic curves are
  refused;
- points are read at one time code (the start frame) in the prim's local space; the prim's
  local-to-world transform is read up front at the frames the simulation needs
  (:mod:`dftl_warp.usd.sampling`): the Scene is plain data and no stage stays open;
- ``dftl:`` attributes are checked against the options table (:mod:`dftl_warp.options`, via
  :mod:`dftl_warp.usd.attributes`); unknown ones get a did-you-mean warning;
- BasisCurves under instanceable prims are not simulated (a warning names each instance);
- gravity comes from a ``UsdPhysics.Scene`` prim, else 9.81 m/s^2 along -upAxis, in stage units;
- colliders are prims with ``UsdPhysics.CollisionAPI`` (Sphere, Capsule, Cube, Mesh);
- optional per-prim settings live in the ``dftl:`` namespace.

Every problem with the input raises :class:`~dftl_warp.errors.UserError` with one line naming the
file, the prim and, for array entries, the index.
"""

from __future__ import annotations

import os
import re

import numpy as np

from ..checks import check_lengths
from ..errors import UserError, check_path
from ..options import OPTIONS
from . import curves as curve_checks
from .attributes import read_values, unknown_attributes
from .colliders import fan_triangulate as _fan_triangulate  # noqa: F401  (old private name)
from .colliders import first_bad_row as _first_bad_row
from .colliders import fmt_point as _fmt_point
from .colliders import read_collider_prim, read_root_mesh
from .guides import check_guides, read_guide_paths
from .material import read_bend_scale, read_curve_material, read_rest_points
from .sampling import TransformReader, scale_growth
from .scene import CurveSettings, CurvesPrim, Scene
from .stage import STANDARD_GRAVITY, layer_unit_warnings, read_gravity, read_stage_info, tf_message, up_vector  # noqa: F401
from .stage import diagnostic_text, open_failure

#: old private name of :func:`dftl_warp.usd.stage.tf_message`
_tf_message = tf_message

USD_EXTENSIONS = (".usd", ".usda", ".usdc", ".usdz")


# -- opening ------------------------------------------------------------------------------------


def open_stage(path: str):
    """Open ``path`` as a Usd.Stage; returns ``(stage, warnings)``.

    Missing, unreadable, non-USD and malformed files raise :class:`UserError`. Warnings USD posts
    while composing (missing sublayers, references) are returned as one-line strings.
    """
    from pxr import Sdf, Tf, Usd, UsdUtils

    path = os.fspath(path)
    if not os.path.exists(path):
        raise UserError(f"{path}: no such file")
    if os.path.isdir(path):
        raise UserError(f"{path}: is a directory, not a USD file")
    ext = os.path.splitext(path)[1].lower()
    if ext not in USD_EXTENSIONS or Sdf.FileFormat.FindByExtension(ext[1:]) is None:
        raise UserError(f"{path}: not a USD file (expected {', '.join(USD_EXTENSIONS)})")
    try:
        with open(path, "rb") as f:
            f.read(1)
    except OSError as exc:
        raise UserError(f"{path}: cannot read: {exc.strerror or exc}") from None
    delegate = UsdUtils.CoalescingDiagnosticDelegate()
    try:
        stage = Usd.Stage.Open(path, Usd.Stage.LoadAll)
    except Tf.ErrorException as exc:
        raise open_failure(path, exc) from None
    finally:
        diagnostics = delegate.TakeUncoalescedDiagnostics()
        del delegate
    if stage is None:
        raise UserError(f"{path}: cannot open as a USD stage")
    warnings = []
    for d in diagnostics:
        text = re.sub(r"\s*\(instantiating stage on stage @[^)]*\)\s*$", "", diagnostic_text(d))
        warnings.append(f"{path}: {' '.join(text.split())}")
    return stage, warnings


# -- curves --------------------------------------------------------------------------------------


def _time_code(time):
    from pxr import Usd

    return Usd.TimeCode.Default() if time is None else Usd.TimeCode(float(time))


#: the per-prim solver settings among the curves' dftl: attributes (the others turn features on)
_SETTINGS = ("simulate", "solver", "damping", "correction", "substeps", "inverse_statics", "bending")


def _split_values(values: dict) -> tuple[CurveSettings, dict]:
    """(solver settings, feature values) of a curves prim's checked ``dftl:`` values."""
    s = CurveSettings()
    for name in _SETTINGS:
        attr = OPTIONS[name].usd
        if attr in values:
            setattr(s, name, values[attr])
    settings_attrs = {OPTIONS[n].usd for n in _SETTINGS}
    return s, {k: v for k, v in values.items() if k not in settings_attrs}


def read_feature_values(prim, where: str, scope: str, time_codes_per_second: float) -> dict:
    """The authored feature ``dftl:`` attributes of ``prim`` valid in ``scope`` ("scene" or
    "curves"), checked against the options table; a time-sampled ``dftl:wind`` becomes keyframes
    (K, 4) of (seconds, vx, vy, vz)."""
    from ..options import FEATURE_ATTRIBUTES

    values = read_values(prim, where, scope, time_codes_per_second)
    return {k: v for k, v in values.items() if k in FEATURE_ATTRIBUTES}


def _changes(attr, code) -> bool:
    """Whether a time-sampled attribute holds another value at some sample than at ``code``."""
    first = np.asarray(attr.Get(code))
    for t in attr.GetTimeSamples():
        other = np.asarray(attr.Get(t))
        if other.shape != first.shape or not np.array_equal(other, first):
            return True
    return False


def _read_widths(prim, curves, code, counts, n_points, ctype, basis, wrap, where, warnings):
    """(widths, interpolation) as the renderer reads them (``primvars:widths`` wins over
    ``widths``; an empty array is none), checked by the renderer's rule; (None, "") when none.
    Time-sampled widths get one warning: only those at ``code`` are simulated."""
    from pxr import UsdGeom

    pv = UsdGeom.PrimvarsAPI(prim).GetPrimvar("widths")
    if pv and pv.HasAuthoredValue():
        values, interp, name = curve_checks.flattened(pv, code, where), str(pv.GetInterpolation()), "primvars:widths"
        sampled = [a for a in (pv.GetAttr(), pv.GetIndicesAttr()) if a and a.GetNumTimeSamples() > 1]
    else:
        attr = curves.GetWidthsAttr()
        values = attr.Get(code) if attr.HasAuthoredValue() else None
        interp, name = str(curves.GetWidthsInterpolation()), "widths"
        sampled = [attr] if attr.GetNumTimeSamples() > 1 else []
    changing = [a for a in sampled if _changes(a, code)]
    if changing and values is not None:
        at = "the default time" if code.IsDefault() else f"time {code.GetValue():g}"
        warnings.append(f"{where}: {changing[0].GetName()} changes over time ({changing[0].GetNumTimeSamples()} "
                        f"samples): only the widths at {at} are read and simulated")
    values = None if values is None else curve_checks.numbers(values, name, where)
    if values is None or len(values) == 0:
        return None, ""
    w = curve_checks.check_primvar(values, interp, counts, n_points, ctype, basis, wrap, name, where, nonnegative=True,
                                   length=True)
    return w.reshape(-1), interp


def read_curves_prim(prim, file: str, time=None, time_codes_per_second: float = 24.0, *,
                     warnings: list | None = None, transforms: TransformReader | None = None,
                     materials_seen: set | None = None) -> CurvesPrim | None:
    """One BasisCurves prim -> CurvesPrim (None for a prim without curves). ``warnings`` collects
    one-line notes (time-sampled points); ``transforms`` reads the prim's transform (default: at
    ``time`` and the prim's authored time samples)."""
    from pxr import UsdGeom

    where = f"{file}: {prim.GetPath()}"
    warnings = [] if warnings is None else warnings
    transforms = transforms or TransformReader(prim.GetStage(), file)
    curves = UsdGeom.BasisCurves(prim)
    code = _time_code(time)
    samples = curves.GetPointsAttr().GetTimeSamples()
    if time is None and samples and curves.GetPointsAttr().Get(code) is None:
        # no start frame and points only time-sampled: USD has no value at the default time
        code = _time_code(samples[0])
        warnings.append(f"{where}: points have only time samples and the stage no startTimeCode: read at their "
                        f"first sample, time {samples[0]:g} (simulate reads them at --start)")
    settings, features = _split_values(read_values(prim, where, "curves", time_codes_per_second))
    root_mesh = read_root_mesh(prim, where, file, time, transforms)

    wrap = str(curves.GetWrapAttr().Get() or "nonperiodic")
    ctype = str(curves.GetTypeAttr().Get() or "cubic")
    basis = str(curves.GetBasisAttr().Get() or "bezier")
    if wrap == "periodic":
        raise UserError(f"{where}: periodic curves (wrap = periodic) cannot be simulated: a hair needs a free tip")
    if wrap not in ("nonperiodic", "pinned"):
        raise UserError(f"{where}: wrap = {wrap!r}: expected nonperiodic or pinned")
    if ctype not in ("linear", "cubic"):
        raise UserError(f"{where}: type = {ctype!r}: expected linear or cubic")
    if ctype == "cubic" and basis not in ("bezier", "bspline", "catmullRom"):
        raise UserError(f"{where}: basis = {basis!r}: expected bezier, bspline or catmullRom")

    if ctype == "cubic" and wrap == "nonperiodic" and basis in ("bspline", "catmullRom"):
        warnings.append(f"{where}: nonperiodic cubic {basis} curves do not pass through their first control point "
                        f"(vertex 0, the root the simulation pins): the drawn root is another point, free to move as "
                        f"the strand swings; author wrap = \"pinned\" to draw each curve from its root")
    points_attr = curves.GetPointsAttr()
    raw_counts = curves.GetCurveVertexCountsAttr().Get(code)
    raw_points = points_attr.Get(code)
    counts = curve_checks.vertex_counts(raw_counts, where)
    points = np.array(raw_points if raw_points is not None else [], dtype=np.float64)
    if points.size and (points.ndim != 2 or points.shape[1] != 3):
        specs = points_attr.GetPropertyStack(code)
        authored_type = specs[0].typeName if specs else points_attr.GetTypeName()
        raise UserError(f"{where}: points is {authored_type}: expected point3f[] (3 coordinates a point)")
    points = points.reshape(-1, 3)
    if counts.size == 0 and points.shape[0] == 0:
        return None
    if counts.size == 0:
        raise UserError(f"{where}: curveVertexCounts is empty but points has {points.shape[0]} entries")
    low = np.flatnonzero(counts < 1)
    if low.size:
        i = int(low[0])
        raise UserError(f"{where}: curveVertexCounts[{i}] = {int(counts[i])}: every curve needs at least 1 vertex")
    total = int(counts.sum())
    if total != points.shape[0]:
        raise UserError(
            f"{where}: curveVertexCounts sum to {total} but points has {points.shape[0]} entries"
        )
    curve_checks.check_vertex_counts(counts, ctype, basis, wrap, where)
    curve_checks.note_single_vertex(counts, where, warnings)
    bad = _first_bad_row(points)
    if bad is not None:
        raise UserError(f"{where}: points[{bad}] = {_fmt_point(points[bad])} is not finite")
    counts_attr = curves.GetCurveVertexCountsAttr()
    if counts_attr.GetNumTimeSamples() > 1:
        for t in counts_attr.GetTimeSamples():
            other = np.array(counts_attr.Get(t) or [], dtype=np.int64)
            if other.shape != counts.shape or np.any(other != counts):
                raise UserError(f"{where}: curveVertexCounts changes at time {t:g}: the curves' topology must not change over time")
    if points_attr.GetNumTimeSamples() > 1:
        at = "the default time" if code.IsDefault() else f"time {code.GetValue():g}"
        warnings.append(
            f"{where}: points are time-sampled (an animated groom): only the points at {at} are read "
            f"and simulated; the roots follow the prim's transform, not the animated points")

    transform, animated = transforms.sampler(prim, time)
    m = transform(time)
    growth = scale_growth(transform, time)
    if growth > 1.0 + 1e-6:
        at = "the default time" if time is None else f"time {float(time):g}"
        warnings.append(f"{where}: its transform's scale changes over time (up to {growth:.4g}x its scale at {at}): "
                        f"the roots follow it, the strands keep their lengths and widths at {at}")
    world = points @ m[:3, :3] + m[3, :3]
    bad = _first_bad_row(world)
    if bad is not None:
        raise UserError(f"{where}: points[{bad}] = {_fmt_point(points[bad])} is not finite in world space")
    check_lengths(world, "points", where, world=" in world space")

    widths, widths_interpolation = _read_widths(prim, curves, code, counts, points.shape[0], ctype, basis, wrap, where,
                                                warnings)
    stretch = np.linalg.svd(m[:3, :3], compute_uv=False)
    if widths is not None and stretch[0] > stretch[-1] * (1.0 + 1e-6):
        warnings.append(f"{where}: widths under the non-uniform scale {tuple(float(f'{v:.4g}') for v in stretch)} "
                        f"(the transform's principal scales): simulated as round hair of the widths times the mean "
                        f"scale {float(np.prod(stretch)) ** (1 / 3):.4g}")
    material = read_curve_material(prim, where, file, warnings, set() if materials_seen is None else materials_seen)
    rest_points = read_rest_points(prim, code, points.shape[0], where, warnings)
    bend_scale = read_bend_scale(prim, code, counts, points.shape[0], ctype, basis, wrap, where)
    normals = tuple(name for name in ("normals", "primvars:normals")
                    if prim.GetAttribute(name) and prim.GetAttribute(name).HasAuthoredValue())
    if normals:
        warnings.append(f"{where}: {' and '.join(normals)} describe the authored shape and would stay at rest "
                        f"while the points move: the output blocks them (renderers compute curve normals)")
    color_pv = UsdGeom.Gprim(prim).GetDisplayColorPrimvar()
    color = color_pv.Get(code) if color_pv and color_pv.HasAuthoredValue() else None
    color = None if color is None else curve_checks.colors(color, color_pv.GetAttr().GetName(), where)
    return CurvesPrim(
        path=str(prim.GetPath()),
        points=points,
        counts=counts,
        type=ctype,
        basis=basis,
        wrap=wrap,
        widths=widths,
        widths_interpolation=widths_interpolation,
        display_color=color,
        display_color_interpolation=str(color_pv.GetInterpolation()) if color is not None else "",
        transform=transform,
        animated=animated,
        settings=settings,
        features=features,
        root_mesh=root_mesh,
        material=material,
        rest_points=rest_points,
        bend_scale=bend_scale,
        normals=normals,
        guides=read_guide_paths(prim, file),
    )


# -- which prims ---------------------------------------------------------------------------------


#: USD's composition warnings for a sublayer, reference or payload that did not load
_UNRESOLVED = re.compile(r"Could not (load|open) (sublayer|asset)|Unresolved (reference|payload) prim path")


def _unresolved(warnings, file: str, under=None) -> str:
    """`` (USD: ...)``: the first composition warning of a sublayer, reference or payload that did
    not load (on a prim at, above or below ``under`` when given); "" when there is none."""
    from pxr import Sdf

    for w in warnings or ():
        if not _UNRESOLVED.search(w):
            continue
        at = re.match(rf"{re.escape(file)}: In <(/[^>]*)>", w)
        if under is not None and at and Sdf.Path.IsValidPathString(at.group(1)):
            where = Sdf.Path(at.group(1))
            if not (under.HasPrefix(where) or where.HasPrefix(under)):
                continue
        return f" (USD: {w.removeprefix(file + ': ')})"
    return ""


def _instanced_curves(prim):
    """The first BasisCurves instance proxy at or below the instance ``prim``, or None."""
    from pxr import Usd, UsdGeom

    for p in Usd.PrimRange(prim, Usd.TraverseInstanceProxies(Usd.PrimDefaultPredicate)):
        if p.IsA(UsdGeom.BasisCurves):
            return p
    return None


def _instance_root(prim):
    """The instanceable prim whose instance proxy ``prim`` is."""
    p = prim
    while p and not p.IsInstance():
        p = p.GetParent()
    return p


def _point_instancer(prim):
    """The PointInstancer ``prim`` lies under (in its prototypes), or None."""
    from pxr import UsdGeom

    p = prim.GetParent()
    while p and not p.IsPseudoRoot():
        if p.IsA(UsdGeom.PointInstancer):
            return p
        p = p.GetParent()
    return None


def _instance_warning(file: str, instance, proxy) -> str:
    return (f"{file}: {instance.GetPath()}: BasisCurves under an instanceable prim (such as {proxy.GetPath()}) are "
            f"not simulated: the output cannot override instance proxies; set instanceable = false on "
            f"{instance.GetPath()} to simulate them")


def _select_prims(stage, file: str, selection, warnings: list | None = None):
    """BasisCurves prims of the whole stage, or at/below each selected path. Grooms under
    instanceable prims or in a PointInstancer's prototypes are not simulated: a warning names each
    such instance or instancer (a selected path inside an instance, or an inactive one, is refused)."""
    from pxr import Sdf, Usd, UsdGeom

    warnings = [] if warnings is None else warnings
    roots = [(None, stage.GetPseudoRoot())] if not selection else []
    for text in selection or ():
        if not Sdf.Path.IsValidPathString(str(text)) or not Sdf.Path(str(text)).IsAbsolutePath():
            raise UserError(f"{file}: {text}: not an absolute prim path")
        prim = stage.GetPrimAtPath(str(text))
        if not prim:
            above = Sdf.Path(str(text)).GetParentPath()
            while above != Sdf.Path.absoluteRootPath and not stage.GetPrimAtPath(above):
                above = above.GetParentPath()
            if above != Sdf.Path.absoluteRootPath and not stage.GetPrimAtPath(above).IsActive():
                raise UserError(f"{file}: {text}: under the inactive prim {above} (active = false): not composed")
            raise UserError(f"{file}: {text}: no such prim")
        if not prim.IsActive():
            raise UserError(f"{file}: {text}: the prim is inactive (active = false): its hair is not simulated")
        if prim.IsInstanceProxy():
            instance = _instance_root(prim)
            raise UserError(f"{file}: {text}: inside the instanceable prim {instance.GetPath()}: the output cannot "
                            f"override instance proxies; set instanceable = false on it to simulate this groom")
        roots.append((text, prim))
    found, seen, instances, others, prototypes = [], set(), [], {}, {}
    for text, root in roots:
        under = []
        for p in Usd.PrimRange(root):
            if p.IsA(UsdGeom.BasisCurves):
                under.append(p)
            elif p.IsA(UsdGeom.Curves) and p.GetPath() not in seen:   # NurbsCurves, HermiteCurves
                seen.add(p.GetPath())
                others.setdefault(str(p.GetTypeName()), []).append(str(p.GetPath()))
            if p.IsInstance() and p.GetPath() not in seen:
                proxy = _instanced_curves(p)
                if proxy is not None:
                    seen.add(p.GetPath())
                    instances.append((p, proxy))
        if selection and not under and not any(i.GetPath().HasPrefix(root.GetPath()) for i, _ in instances):
            raise UserError(f"{file}: {text}: no BasisCurves prim at or below this path"
                            f"{_unresolved(warnings, file, root.GetPath())}")
        for p in under:
            if p.GetPath() not in seen:
                seen.add(p.GetPath())
                instancer = _point_instancer(p)
                if instancer is None:
                    found.append(p)
                else:
                    prototypes.setdefault(str(instancer.GetPath()), str(p.GetPath()))
    for instance, proxy in instances:
        warnings.append(_instance_warning(file, instance, proxy))
    for instancer, example in prototypes.items():
        warnings.append(f"{file}: {instancer}: BasisCurves in the prototypes of a PointInstancer (such as {example}) "
                        f"are not simulated: one simulation in the prototype's space cannot move each instance in "
                        f"its own place; move the groom out of the PointInstancer to simulate it")
    skipped = "; ".join(f"{len(paths)} {kind} prim{'s' if len(paths) > 1 else ''} ({', '.join(paths[:3])}"
                        f"{' ...' if len(paths) > 3 else ''})" for kind, paths in others.items())
    if skipped:
        warnings.append(f"{file}: {skipped}: not simulated (only BasisCurves are); skipped")
    if not found:
        if prototypes:
            raise UserError(f"{file}: every BasisCurves prim is in the prototypes of a PointInstancer "
                            f"({', '.join(prototypes)}): move the groom out of it to simulate it")
        if instances:
            raise UserError(f"{file}: every BasisCurves prim is under an instanceable prim ({instances[0][0].GetPath()}"
                            f"{' ...' if len(instances) > 1 else ''}): set instanceable = false to simulate them")
        if not selection:
            # a layer, reference or payload that did not load (a cache whose input moved) is the likely
            # reason: say so
            because = _unresolved(warnings, file) or (f" ({skipped}: only BasisCurves are simulated)" if skipped else "")
            raise UserError(f"{file}: the stage has no BasisCurves prims (no hair to simulate){because}")
    return found


# -- guides (issue 22) ------------------------------------------------------------------------------


def _add_guide_prims(stage, file, curves, time, tcps, warnings, transforms, materials_seen) -> None:
    """Read the guide prims that render prims name (``rel dftl:guides``) but the selection left
    out, and check the render prims against their guides (:mod:`dftl_warp.usd.guides`)."""
    have = {c.path for c in curves}
    for c in list(curves):
        for g in c.guides:
            if g in have:
                continue
            have.add(g)
            guide = read_curves_prim(stage.GetPrimAtPath(g), file, time, tcps, warnings=warnings,
                                     transforms=transforms, materials_seen=materials_seen)
            if guide is not None and guide.settings.simulate:
                curves.append(guide)
    check_guides(curves, file)


# -- the scene -----------------------------------------------------------------------------------


def _scan(stage, file: str, holder, warnings: list):
    """Collider prims, and one warning per prim with unknown (or misplaced) ``dftl:`` attributes."""
    from pxr import UsdGeom, UsdPhysics

    colliders = []
    for prim in stage.Traverse():
        scopes = []
        if prim.IsA(UsdGeom.BasisCurves):
            scopes.append("curves")
        if prim.HasAPI(UsdPhysics.CollisionAPI):
            scopes.append("collider")
            colliders.append(prim)
        if holder and prim.GetPath() == holder.GetPath():
            scopes.append("scene")
        note = unknown_attributes(prim, f"{file}: {prim.GetPath()}", scopes)
        if note is not None:
            warnings.append(note)
    return colliders


def read_scene(source, *, prims=None, time=None, frames=None) -> Scene:
    """Read ``source`` (a path, or an open Usd.Stage) into a :class:`Scene` (plain data: it
    holds no USD object and pickles).

    Args:
        prims: optional prim paths; only BasisCurves prims at or below them are read.
        time: time code to read points at; default the stage's startTimeCode (the default time
            when the stage has no time code range).
        frames: optional ``(first, last)`` frames of the run; animated transforms are read at
            every integer frame of their animation within them (default: of their whole
            animation; see :mod:`dftl_warp.usd.sampling`).
    """
    from pxr import Usd, UsdUtils

    if isinstance(source, Usd.Stage):
        stage, warnings = source, []
        file = source.GetRootLayer().identifier
    else:
        check_path("source", source)   # a path, or the open Usd.Stage above
        file = os.fspath(source)
        stage, warnings = open_stage(file)
    # USD's own warnings while reading (an xformOp in xformOpOrder that is not authored) become one
    # line each naming the file, as open_stage's do, instead of USD's "Warning: in ..." on stderr
    delegate = UsdUtils.CoalescingDiagnosticDelegate()
    try:
        scene = _read_scene(stage, file, warnings, prims, time, frames)
    finally:
        diagnostics = delegate.TakeUncoalescedDiagnostics()
        del delegate
    seen = set()
    for d in diagnostics:
        text = " ".join(diagnostic_text(d).split())
        if text not in seen:
            seen.add(text)
            scene.warnings.append(f"{file}: {text}")
    return scene


def _read_scene(stage, file: str, warnings: list, prims, time, frames) -> Scene:
    from pxr import UsdPhysics

    info = read_stage_info(stage, file)
    if "metersPerUnit" not in info.authored:
        warnings.append(f"{file}: the stage does not author metersPerUnit: USD's fallback, {info.meters_per_unit:g} m "
                        f"per unit (centimetres), is used, so gravity is {STANDARD_GRAVITY / info.meters_per_unit:g} "
                        f"units/s^2; author metersPerUnit (1 for a scene in metres)")
    warnings += layer_unit_warnings(stage, info, file)
    if time is None and info.start_time_code is not None:
        time = info.start_time_code
    gravity = read_gravity(stage, info, file, warnings)
    transforms = TransformReader(stage, file, frames)

    curves, materials_seen = [], set()
    for prim in _select_prims(stage, file, prims, warnings):
        c = read_curves_prim(prim, file, time, info.time_codes_per_second, warnings=warnings, transforms=transforms,
                             materials_seen=materials_seen)
        if c is None:
            warnings.append(f"{file}: {prim.GetPath()}: no curves; skipped")
        elif not c.settings.simulate:
            warnings.append(f"{file}: {prim.GetPath()}: dftl:simulate = false; skipped")
        else:
            curves.append(c)
    if not curves:
        raise UserError(f"{file}: no curves to simulate (every selected BasisCurves prim is empty or has dftl:simulate = false)")
    _add_guide_prims(stage, file, curves, time, info.time_codes_per_second, warnings, transforms, materials_seen)

    scene_prims = [p for p in stage.Traverse() if p.IsA(UsdPhysics.Scene)]
    holder = scene_prims[0] if scene_prims else stage.GetDefaultPrim()
    colliders = []
    for prim in _scan(stage, file, holder, warnings):
        c = read_collider_prim(prim, file, time, warnings, transforms)
        if c is not None:
            colliders.append(c)
    features = {}
    if holder:
        features = read_feature_values(holder, f"{file}: {holder.GetPath()}", "scene", info.time_codes_per_second)
    return Scene(
        features=features,
        source=file,
        stage=info,
        gravity=gravity,
        curves=curves,
        colliders=colliders,
        read_time=time,
        warnings=warnings,
    )
