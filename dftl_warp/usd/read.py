"""The one module that reads USD for simulation: a stage -> :class:`~dftl_warp.usd.scene.Scene`.

Rules (``docs/usd.md`` is the user-facing version):

- hair is every ``UsdGeom.BasisCurves`` prim (or those at/below the ``prims`` selection); vertex 0
  of each curve is its root; cubic curves contribute their control points; periodic curves are
  refused;
- points are read at one time code (the start frame) in the prim's local space; the prim's
  local-to-world transform is kept as a sampler for the simulation to move the roots with;
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

from ..errors import UserError
from ..features.attributes import ATTRIBUTES as FEATURE_ATTRIBUTES
from .scene import ColliderPrim, CurveSettings, CurvesPrim, MeshSource, Scene, StageInfo, constant_transform

#: standard gravity, m/s^2
STANDARD_GRAVITY = 9.81

#: the ``dftl:`` attributes read from BasisCurves prims: name -> (python type, description)
CURVE_ATTRIBUTES = {
    "dftl:simulate": (bool, "false leaves the prim out of the simulation"),
    "dftl:solver": (str, "solver name (see dftl_warp.solvers.dftl.SOLVERS)"),
    "dftl:damping": (float, "share s in [0, 1] of the follow-the-leader correction removed from velocities"),
    "dftl:correction": (str, "velocity correction form: prior or posterior"),
    "dftl:substeps": (int, "solver steps per frame, >= 1"),
}
#: the ``dftl:`` attributes read from collider prims
COLLIDER_ATTRIBUTES = {
    "dftl:friction": (float, "Coulomb friction coefficient >= 0 (overrides the physics material)"),
}

USD_EXTENSIONS = (".usd", ".usda", ".usdc", ".usdz")


# -- opening ------------------------------------------------------------------------------------


def _tf_message(exc: Exception) -> str:
    """The first message of a Tf.ErrorException, on one line, without C++ decorations."""
    text = str(exc)
    found = re.findall(r"Error in '[^']*' at line \d+ in file [^:]+ : '(.*?)'\s*(?=\n\tError in|$)", text, re.S)
    message = found[0] if found else text.strip()
    message = re.sub(r"pxrInternal_v[0-9_]+?__pxrReserved__(_?)::", "", message)
    message = re.sub(r"\bSdf_\w+::|\b_pegtl::", "", message)
    return " ".join(message.split())


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
        message = _tf_message(exc)
        prefix = os.path.abspath(path) + ":"
        if message.startswith(prefix):  # parser messages start with the file name
            message = message[len(prefix):].lstrip()
            where = re.match(r"(\d+:\d+):\s*(.*)", message, re.S)
            if where:
                raise UserError(f"{path}:{where.group(1)}: syntax error: {where.group(2)}") from None
            raise UserError(f"{path}: {message}") from None
        raise UserError(f"{path}: cannot open as a USD stage: {message}") from None
    finally:
        diagnostics = delegate.TakeUncoalescedDiagnostics()
        del delegate
    if stage is None:
        raise UserError(f"{path}: cannot open as a USD stage")
    warnings = []
    for d in diagnostics:
        text = re.sub(r"\s*\(instantiating stage on stage @[^)]*\)\s*$", "", d.commentary)
        warnings.append(f"{path}: {' '.join(text.split())}")
    return stage, warnings


# -- stage metadata and gravity ----------------------------------------------------------------


def read_stage_info(stage) -> StageInfo:
    """Effective stage metadata (USD fallbacks applied) and which fields the root layer authors."""
    from pxr import UsdGeom

    root = stage.GetRootLayer()
    authored = tuple(
        k for k in ("upAxis", "metersPerUnit", "timeCodesPerSecond", "framesPerSecond",
                    "startTimeCode", "endTimeCode", "defaultPrim")
        if root.pseudoRoot.HasInfo(k)
    )
    has_range = stage.HasAuthoredTimeCodeRange()
    return StageInfo(
        up_axis=str(UsdGeom.GetStageUpAxis(stage)),
        meters_per_unit=float(UsdGeom.GetStageMetersPerUnit(stage)),
        time_codes_per_second=float(stage.GetTimeCodesPerSecond()),
        frames_per_second=float(stage.GetFramesPerSecond()) if root.HasFramesPerSecond() else None,
        start_time_code=float(stage.GetStartTimeCode()) if has_range else None,
        end_time_code=float(stage.GetEndTimeCode()) if has_range else None,
        default_prim=str(root.defaultPrim or ""),
        authored=authored,
    )


def up_vector(up_axis: str) -> np.ndarray:
    return np.array([0.0, 0.0, 1.0]) if up_axis == "Z" else np.array([0.0, 1.0, 0.0])


def read_gravity(stage, info: StageInfo, file: str, warnings: list) -> np.ndarray:
    """Gravity (3,) in stage units/s^2.

    From the first ``UsdPhysics.Scene`` prim: ``gravityDirection`` (a zero vector means -upAxis)
    times ``gravityMagnitude`` (negative means earth gravity, 9.81 m/s^2 in stage units). Without
    a physics scene: 9.81 m/s^2 along -upAxis.
    """
    from pxr import UsdPhysics

    earth = STANDARD_GRAVITY / info.meters_per_unit
    default = -up_vector(info.up_axis) * earth + 0.0  # + 0.0: no negative zeros
    scenes = [p for p in stage.Traverse() if p.IsA(UsdPhysics.Scene)]
    if not scenes:
        return default
    if len(scenes) > 1:
        warnings.append(f"{file}: {len(scenes)} UsdPhysics.Scene prims; using {scenes[0].GetPath()}")
    phys = UsdPhysics.Scene(scenes[0])
    where = f"{file}: {scenes[0].GetPath()}"
    direction = np.array(phys.GetGravityDirectionAttr().Get() or (0.0, 0.0, 0.0), dtype=np.float64)
    magnitude = phys.GetGravityMagnitudeAttr().Get()
    magnitude = float("-inf") if magnitude is None else float(magnitude)
    if not np.all(np.isfinite(direction)):
        raise UserError(f"{where}: gravityDirection {tuple(direction)} is not finite")
    if np.isnan(magnitude) or magnitude == float("inf"):
        raise UserError(f"{where}: gravityMagnitude {magnitude} is not finite")
    norm = float(np.linalg.norm(direction))
    unit = -up_vector(info.up_axis) if norm == 0.0 else direction / norm
    return unit * (earth if magnitude < 0.0 else magnitude) + 0.0


# -- transforms ----------------------------------------------------------------------------------


def _transform_sampler(prim, read_time, file: str):
    """(sampler, animated) for the prim's local-to-world transform."""
    from pxr import Usd, UsdGeom

    imageable = UsdGeom.Imageable(prim)
    stage = prim.GetStage()  # the sampler keeps the stage alive (prims only hold weak references)
    animated = False
    p = prim
    while p and not p.IsPseudoRoot():
        xf = UsdGeom.Xformable(p)
        if xf:
            if xf.TransformMightBeTimeVarying():
                animated = True
                break
            if xf.GetResetXformStack():
                break
        p = p.GetParent()

    where = f"{file}: {prim.GetPath()}"

    def sample(time):
        code = Usd.TimeCode.Default() if time is None else Usd.TimeCode(float(time))
        assert stage
        m = np.array(imageable.ComputeLocalToWorldTransform(code), dtype=np.float64)
        if not np.all(np.isfinite(m)):
            raise UserError(f"{where}: local-to-world transform at time {time} is not finite")
        if abs(np.linalg.det(m[:3, :3])) < 1e-300:
            raise UserError(f"{where}: local-to-world transform at time {time} is singular (zero scale)")
        return m

    if not animated:
        return constant_transform(sample(read_time)), False
    sample(read_time)  # validate now rather than mid-simulation
    return sample, True


# -- curves --------------------------------------------------------------------------------------


def _time_code(time):
    from pxr import Usd

    return Usd.TimeCode.Default() if time is None else Usd.TimeCode(float(time))


def _read_settings(prim, where: str) -> CurveSettings:
    from ..kernels.solvers.ftl import CORRECTIONS
    from ..solvers import SOLVERS

    s = CurveSettings()
    values = {}
    for name, (kind, _) in CURVE_ATTRIBUTES.items():
        attr = prim.GetAttribute(name)
        if not attr or not attr.HasAuthoredValue():
            continue
        value = attr.Get()
        ok = (
            isinstance(value, bool) if kind is bool
            else isinstance(value, str) if kind is str
            else isinstance(value, (int, float)) and not isinstance(value, bool)
        )
        if kind is int and ok and float(value) != int(value):
            ok = False
        if not ok:
            raise UserError(f"{where}: {name} = {value!r}: expected a {kind.__name__}")
        values[name] = value
    if "dftl:simulate" in values:
        s.simulate = bool(values["dftl:simulate"])
    if "dftl:solver" in values:
        if values["dftl:solver"] not in SOLVERS:
            raise UserError(f"{where}: dftl:solver = {values['dftl:solver']!r}: choose one of {', '.join(SOLVERS)}")
        s.solver = values["dftl:solver"]
    if "dftl:damping" in values:
        d = float(values["dftl:damping"])
        if not (0.0 <= d <= 1.0):
            raise UserError(f"{where}: dftl:damping = {d}: must be in [0, 1]")
        s.damping = d
    if "dftl:correction" in values:
        if values["dftl:correction"] not in CORRECTIONS:
            raise UserError(f"{where}: dftl:correction = {values['dftl:correction']!r}: choose prior or posterior")
        s.correction = values["dftl:correction"]
    if "dftl:substeps" in values:
        n = int(values["dftl:substeps"])
        if n < 1:
            raise UserError(f"{where}: dftl:substeps = {n}: must be >= 1")
        s.substeps = n
    return s


def read_feature_values(prim, where: str, scope: str, time_codes_per_second: float) -> dict:
    """The authored feature ``dftl:`` attributes of ``prim`` valid in ``scope`` ("scene" or
    "curves"), checked for type; a time-sampled ``dftl:wind`` becomes keyframes (K, 4) of
    (seconds, vx, vy, vz)."""
    values = {}
    for name, (kind, allowed, _) in FEATURE_ATTRIBUTES.items():
        if kind == "rel" or allowed not in (scope, "both"):
            continue
        attr = prim.GetAttribute(name)
        if not attr or not attr.HasAuthoredValue():
            continue
        if kind == "float3":
            times = attr.GetTimeSamples()
            rows = [(t, attr.Get(t)) for t in times] if times else [(0.0, attr.Get())]
            keys = []
            for t, v in rows:
                try:
                    v = np.array(v, dtype=np.float64).reshape(3)
                except (TypeError, ValueError):
                    raise UserError(f"{where}: {name} = {v!r}: expected 3 numbers") from None
                if not np.isfinite(v).all():
                    raise UserError(f"{where}: {name} at time {t:g} is not finite")
                keys.append([t / time_codes_per_second, *v])
            values[name] = np.array(keys) if times else np.array(keys[0][1:])
            continue
        value = attr.Get()
        ok = (isinstance(value, bool) if kind is bool
              else isinstance(value, (int, float)) and not isinstance(value, bool))
        if ok and kind is int and float(value) != int(value):
            ok = False
        if ok and kind is float and not np.isfinite(value):
            ok = False
        if not ok:
            raise UserError(f"{where}: {name} = {value!r}: expected {'a finite number' if kind is float else kind.__name__}")
        values[name] = value
    return values


def _read_root_mesh(prim, where: str, file: str, time):
    """The Mesh prim targeted by ``dftl:rootMesh`` on a curves prim, or None."""
    from pxr import UsdGeom

    rel = prim.GetRelationship("dftl:rootMesh")
    if not rel:
        return None
    targets = rel.GetForwardedTargets()
    if not targets:
        return None
    if len(targets) > 1:
        raise UserError(f"{where}: dftl:rootMesh has {len(targets)} targets; expected one Mesh")
    target = prim.GetStage().GetPrimAtPath(targets[0])
    if not target or not target.IsA(UsdGeom.Mesh):
        raise UserError(f"{where}: dftl:rootMesh -> {targets[0]}: not a Mesh prim")
    mesh_where = f"{file}: {target.GetPath()}"
    mesh = UsdGeom.Mesh(target)
    code = _time_code(time)
    points_attr = mesh.GetPointsAttr()
    pts = np.array(points_attr.Get(code) or [], dtype=np.float64).reshape(-1, 3)
    fvc = np.array(mesh.GetFaceVertexCountsAttr().Get(code) or [], dtype=np.int64)
    fvi = np.array(mesh.GetFaceVertexIndicesAttr().Get(code) or [], dtype=np.int64)
    if pts.shape[0] == 0 or fvc.size == 0 or np.any(fvc < 3) or int(fvc.sum()) != fvi.size \
            or np.any((fvi < 0) | (fvi >= pts.shape[0])):
        raise UserError(f"{mesh_where}: not a valid mesh for dftl:rootMesh (points, faceVertexCounts, faceVertexIndices)")
    count = pts.shape[0]
    stage = target.GetStage()  # the sampler keeps the stage alive (prims only hold weak references)

    def points_at(t):
        assert stage
        p = np.array(points_attr.Get(_time_code(t)) or [], dtype=np.float64).reshape(-1, 3)
        if p.shape[0] != count or not np.isfinite(p).all():
            raise UserError(f"{mesh_where}: points at time {t} are not {count} finite points")
        return p

    deforming = points_attr.ValueMightBeTimeVarying()
    transform, moving = _transform_sampler(target, time, file)
    return MeshSource(str(target.GetPath()), _fan_triangulate(fvc, fvi),
                      points_at if deforming else (lambda t, p=pts: p), transform, bool(deforming or moving))


def _first_bad_row(array: np.ndarray) -> int | None:
    bad = ~np.isfinite(array).all(axis=1)
    return int(np.flatnonzero(bad)[0]) if bad.any() else None


def _fmt_point(p) -> str:
    return "(" + ", ".join(f"{float(v):g}" for v in p) + ")"


def read_curves_prim(prim, file: str, time=None, time_codes_per_second: float = 24.0) -> CurvesPrim | None:
    """One BasisCurves prim -> CurvesPrim (None for a prim without curves)."""
    from pxr import UsdGeom

    where = f"{file}: {prim.GetPath()}"
    curves = UsdGeom.BasisCurves(prim)
    code = _time_code(time)
    settings = _read_settings(prim, where)
    features = read_feature_values(prim, where, "curves", time_codes_per_second)
    root_mesh = _read_root_mesh(prim, where, file, time)

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

    raw_counts = curves.GetCurveVertexCountsAttr().Get(code)
    raw_points = curves.GetPointsAttr().Get(code)
    counts = np.array(raw_counts if raw_counts is not None else [], dtype=np.int64).reshape(-1)
    points = np.array(raw_points if raw_points is not None else [], dtype=np.float64).reshape(-1, 3)
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
    bad = _first_bad_row(points)
    if bad is not None:
        raise UserError(f"{where}: points[{bad}] = {_fmt_point(points[bad])} is not finite")
    counts_attr = curves.GetCurveVertexCountsAttr()
    if counts_attr.GetNumTimeSamples() > 1:
        for t in counts_attr.GetTimeSamples():
            other = np.array(counts_attr.Get(t) or [], dtype=np.int64)
            if other.shape != counts.shape or np.any(other != counts):
                raise UserError(f"{where}: curveVertexCounts changes at time {t:g}: the curves' topology must not change over time")

    transform, animated = _transform_sampler(prim, time, file)
    m = transform(time)
    world = points @ m[:3, :3] + m[3, :3]
    bad = _first_bad_row(world)
    if bad is not None:
        raise UserError(f"{where}: points[{bad}] = {_fmt_point(points[bad])} is not finite in world space")

    widths_attr = curves.GetWidthsAttr()
    widths = widths_attr.Get(code) if widths_attr.HasAuthoredValue() else None
    widths = None if widths is None else np.array(widths, dtype=np.float64).reshape(-1)
    color_pv = UsdGeom.Gprim(prim).GetDisplayColorPrimvar()
    color = color_pv.Get(code) if color_pv and color_pv.HasAuthoredValue() else None
    color = None if color is None else np.array(color, dtype=np.float64).reshape(-1, 3)
    return CurvesPrim(
        path=str(prim.GetPath()),
        points=points,
        counts=counts,
        type=ctype,
        basis=basis,
        wrap=wrap,
        widths=widths,
        widths_interpolation=str(curves.GetWidthsInterpolation()) if widths is not None else "",
        display_color=color,
        display_color_interpolation=str(color_pv.GetInterpolation()) if color is not None else "",
        transform=transform,
        animated=animated,
        settings=settings,
        features=features,
        root_mesh=root_mesh,
    )


def _select_prims(stage, file: str, selection):
    """BasisCurves prims of the whole stage, or at/below each selected path."""
    from pxr import Sdf, Usd, UsdGeom

    if not selection:
        found = [p for p in stage.Traverse() if p.IsA(UsdGeom.BasisCurves)]
        if not found:
            raise UserError(f"{file}: the stage has no BasisCurves prims (no hair to simulate)")
        return found
    found, seen = [], set()
    for text in selection:
        if not Sdf.Path.IsValidPathString(str(text)) or not Sdf.Path(str(text)).IsAbsolutePath():
            raise UserError(f"{file}: {text}: not an absolute prim path")
        prim = stage.GetPrimAtPath(str(text))
        if not prim:
            raise UserError(f"{file}: {text}: no such prim")
        under = [p for p in Usd.PrimRange(prim) if p.IsA(UsdGeom.BasisCurves)]
        if not under:
            raise UserError(f"{file}: {text}: no BasisCurves prim at or below this path")
        for p in under:
            if p.GetPath() not in seen:
                seen.add(p.GetPath())
                found.append(p)
    return found


# -- colliders -----------------------------------------------------------------------------------


def _friction(prim, where: str):
    from pxr import UsdPhysics, UsdShade

    attr = prim.GetAttribute("dftl:friction")
    if attr and attr.HasAuthoredValue():
        value = attr.Get()
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not np.isfinite(value) or value < 0:
            raise UserError(f"{where}: dftl:friction = {value!r}: expected a number >= 0")
        return float(value)
    material, _ = UsdShade.MaterialBindingAPI(prim).ComputeBoundMaterial("physics")
    if material and material.GetPrim().HasAPI(UsdPhysics.MaterialAPI):
        value = UsdPhysics.MaterialAPI(material.GetPrim()).GetDynamicFrictionAttr().Get()
        if value is not None:
            return float(value)
    return None


def read_collider_prim(prim, file: str, time, warnings: list) -> ColliderPrim | None:
    from pxr import UsdGeom, UsdPhysics

    where = f"{file}: {prim.GetPath()}"
    api = UsdPhysics.CollisionAPI(prim)
    enabled = api.GetCollisionEnabledAttr().Get()
    if enabled is False:
        return None
    code = _time_code(time)

    def positive(name, value):
        if value is None or not np.isfinite(value) or value < 0:
            raise UserError(f"{where}: {name} = {value}: expected a finite number >= 0")
        return float(value)

    c = None
    if prim.IsA(UsdGeom.Sphere):
        c = ColliderPrim(str(prim.GetPath()), "sphere", radius=positive("radius", UsdGeom.Sphere(prim).GetRadiusAttr().Get(code)))
    elif prim.IsA(UsdGeom.Capsule):
        cap = UsdGeom.Capsule(prim)
        c = ColliderPrim(
            str(prim.GetPath()), "capsule",
            radius=positive("radius", cap.GetRadiusAttr().Get(code)),
            height=positive("height", cap.GetHeightAttr().Get(code)),
            axis=str(cap.GetAxisAttr().Get(code) or "Z"),
        )
    elif prim.IsA(UsdGeom.Cube):
        size = positive("size", UsdGeom.Cube(prim).GetSizeAttr().Get(code))
        c = ColliderPrim(str(prim.GetPath()), "box", half_extents=np.full(3, 0.5 * size))
    elif prim.IsA(UsdGeom.Mesh):
        mesh = UsdGeom.Mesh(prim)
        pts = np.array(mesh.GetPointsAttr().Get(code) or [], dtype=np.float64).reshape(-1, 3)
        fvc = np.array(mesh.GetFaceVertexCountsAttr().Get(code) or [], dtype=np.int64)
        fvi = np.array(mesh.GetFaceVertexIndicesAttr().Get(code) or [], dtype=np.int64)
        bad = _first_bad_row(pts)
        if bad is not None:
            raise UserError(f"{where}: points[{bad}] = {_fmt_point(pts[bad])} is not finite")
        if np.any(fvc < 3):
            i = int(np.flatnonzero(fvc < 3)[0])
            raise UserError(f"{where}: faceVertexCounts[{i}] = {int(fvc[i])}: a face needs at least 3 vertices")
        if int(fvc.sum()) != fvi.size:
            raise UserError(f"{where}: faceVertexCounts sum to {int(fvc.sum())} but faceVertexIndices has {fvi.size} entries")
        out = np.flatnonzero((fvi < 0) | (fvi >= pts.shape[0]))
        if out.size:
            i = int(out[0])
            raise UserError(f"{where}: faceVertexIndices[{i}] = {int(fvi[i])} is out of range (0..{pts.shape[0] - 1})")
        c = ColliderPrim(str(prim.GetPath()), "mesh", mesh_points=pts, triangles=_fan_triangulate(fvc, fvi))
        points_attr = mesh.GetPointsAttr()
        if points_attr.ValueMightBeTimeVarying():
            count = pts.shape[0]

            def points_at(t, attr=points_attr, where=where, count=count, stage=prim.GetStage()):
                assert stage  # kept alive with the sampler
                p = np.array(attr.Get(_time_code(t)) or [], dtype=np.float64).reshape(-1, 3)
                if p.shape[0] != count or not np.isfinite(p).all():
                    raise UserError(f"{where}: points at time {t} are not {count} finite points")
                return p

            c.points_sampler = points_at
    else:
        warnings.append(f"{where}: collider of type {prim.GetTypeName() or 'untyped'} is not supported; ignored")
        return None
    c.friction = _friction(prim, where)
    c.transform, c.animated = _transform_sampler(prim, time, file)
    return c


def _fan_triangulate(counts: np.ndarray, indices: np.ndarray) -> np.ndarray:
    """Triangles (T, 3) of polygon faces split as fans around their first vertex."""
    starts = np.zeros(counts.size, dtype=np.int64)
    np.cumsum(counts[:-1], out=starts[1:])
    ntri = counts - 2
    face = np.repeat(np.arange(counts.size), ntri)
    k = np.arange(int(ntri.sum())) - np.repeat(np.cumsum(ntri) - ntri, ntri)
    first = starts[face]
    return np.stack([indices[first], indices[first + k + 1], indices[first + k + 2]], axis=1)


# -- the scene -----------------------------------------------------------------------------------


def read_scene(source, *, prims=None, time=None) -> Scene:
    """Read ``source`` (a path, or an open Usd.Stage) into a :class:`Scene`.

    Args:
        prims: optional prim paths; only BasisCurves prims at or below them are read.
        time: time code to read points at; default the stage's startTimeCode (the default time
            when the stage has no time code range).
    """
    from pxr import Usd, UsdPhysics

    if isinstance(source, Usd.Stage):
        stage, warnings = source, []
        file = source.GetRootLayer().identifier
    else:
        file = os.fspath(source)
        stage, warnings = open_stage(file)
    info = read_stage_info(stage)
    if time is None and info.start_time_code is not None:
        time = info.start_time_code
    gravity = read_gravity(stage, info, file, warnings)

    curves = []
    for prim in _select_prims(stage, file, prims):
        c = read_curves_prim(prim, file, time, info.time_codes_per_second)
        if c is None:
            warnings.append(f"{file}: {prim.GetPath()}: no curves; skipped")
        elif not c.settings.simulate:
            warnings.append(f"{file}: {prim.GetPath()}: dftl:simulate = false; skipped")
        else:
            curves.append(c)
    if not curves:
        raise UserError(f"{file}: no curves to simulate (every selected BasisCurves prim is empty or has dftl:simulate = false)")

    colliders = []
    for prim in stage.Traverse():
        if prim.HasAPI(UsdPhysics.CollisionAPI):
            c = read_collider_prim(prim, file, time, warnings)
            if c is not None:
                colliders.append(c)
    features = {}
    scene_prims = [p for p in stage.Traverse() if p.IsA(UsdPhysics.Scene)]
    holder = scene_prims[0] if scene_prims else stage.GetDefaultPrim()
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
