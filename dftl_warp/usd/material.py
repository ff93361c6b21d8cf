"""What the elastic solver reads from USD: a bound curve-deformable physics material, the rest
shape and the stiffness ramp of a BasisCurves prim (plain data on the Scene's ``CurvesPrim``).

- **Material** (:func:`read_curve_material`): the material bound with purpose ``physics``
  (UsdShade's resolution falls back to the all-purpose binding) when it is a curve-deformable
  physics material, as the AOUSD deformable proposal and NVIDIA Newton's importer read it: the
  applied schema ``PhysicsCurvesDeformableMaterialAPI`` with ``physics:youngsModulus``,
  ``physics:poissonsRatio``, ``physics:density`` (UsdPhysics.MaterialAPI) and the overrides
  ``physics:curvesBendStiffness`` (E*I) and ``physics:curvesTwistStiffness`` (G*J). Values stay in
  stage units (UsdPhysics: ``metersPerUnit``, ``kilogramsPerUnit``); the simulation converts the
  solver's SI defaults. A bound physics material without the curve-deformable schema is not read
  (one warning). An authored ``physics:`` attribute close to a known name is an error (a
  misspelling, with a did-you-mean); attributes the solver does not use are warned about once.
- **Rest shape** (:func:`read_rest_points`): ``physics:restShapePoints`` (the proposal's
  ``PhysicsCurvesDeformableSimAPI``), one point per vertex; ``physics:restNormals`` and
  ``physics:masses`` are not used (one warning).
- **Stiffness ramp** (:func:`read_bend_scale`): the primvar ``primvars:dftl:bendStiffnessScale``
  (constant, uniform = per curve, vertex or varying = per vertex; >= 0) scales E*I per vertex.
"""

from __future__ import annotations

import difflib
import math

import numpy as np

from ..errors import UserError
from . import curves as curve_checks
from .scene import CurveMaterial
from .values import shown

#: the applied schema that marks a curve-deformable physics material
CURVES_MATERIAL_API = "PhysicsCurvesDeformableMaterialAPI"
#: the material attributes read: attribute -> (CurveMaterial field, lowest value, low open, highest)
READ = {
    "physics:youngsModulus": ("youngs_modulus", 0.0, True, math.inf),
    "physics:poissonsRatio": ("poissons_ratio", -1.0, True, 0.5),
    "physics:density": ("density", 0.0, True, math.inf),
    "physics:curvesBendStiffness": ("bend_stiffness", 0.0, True, math.inf),
    "physics:curvesTwistStiffness": ("twist_stiffness", 0.0, True, math.inf),
}
#: known material attributes the elastic solver does not use (warned about once)
UNUSED = {
    "physics:staticFriction": "friction: the elastic solver has no contact",
    "physics:dynamicFriction": "friction: the elastic solver has no contact",
    "physics:restitution": "the elastic solver has no contact",
    "physics:thickness": "the radius is half the curves' widths",
    "physics:curvesThickness": "the radius is half the curves' widths",
}
#: the bend-stiffness ramp primvar (docs/usd.md)
BEND_SCALE_PRIMVAR = "dftl:bendStiffnessScale"


def _applied_schemas(prim) -> list[str]:
    """Applied API schema names, unregistered ones (the proposal's) included."""
    return [str(s) for s in prim.GetPrimTypeInfo().GetAppliedAPISchemas()]


def bound_material(prim, where: str, warnings: list, fallback: str):
    """The material bound to ``prim`` for purpose ``physics`` (UsdShade's resolution: the
    all-purpose binding when there is no physics one), a UsdShade.Material, invalid when none.
    A direct binding of ``prim`` (``material:binding:physics``, else ``material:binding``) whose
    target is missing or not a Material gets one warning naming the prim and the target (USD skips
    such a binding); ``fallback`` says what is used instead when no material is bound."""
    from pxr import UsdShade

    api = UsdShade.MaterialBindingAPI(prim)
    material, _ = api.ComputeBoundMaterial("physics")
    for purpose in ("physics", UsdShade.Tokens.allPurpose):
        rel = api.GetDirectBindingRel(purpose)
        targets = rel.GetTargets() if rel else []
        if not targets:
            continue
        target = prim.GetStage().GetPrimAtPath(targets[0])
        if target and target.IsA(UsdShade.Material):
            break
        problem = "no such prim" if not target else f"a {target.GetTypeName() or 'typeless'} prim, not a Material"
        instead = f"{material.GetPath()} is used" if material else fallback
        message = f"{where}: {rel.GetName()} -> {targets[0]}: {problem}: the binding is skipped ({instead})"
        if message not in warnings:
            warnings.append(message)
        break
    return material


def read_curve_material(prim, where: str, file: str, warnings: list, seen: set) -> CurveMaterial | None:
    """The curve-deformable physics material bound to ``prim`` (None when none). ``seen`` holds the
    materials already warned about, so each warning appears once per material."""
    material = bound_material(prim, where, warnings, "the hair has human hair's material")
    if not material:
        return None
    mprim = material.GetPrim()
    path = str(mprim.GetPath())
    mwhere = f"{file}: {path}"
    schemas = _applied_schemas(mprim)
    if CURVES_MATERIAL_API not in schemas:
        if "PhysicsMaterialAPI" in schemas and path not in seen:
            seen.add(path)
            warnings.append(f"{mwhere}: a physics material without {CURVES_MATERIAL_API}: not read for hair "
                            f"(bound to {prim.GetPath()}); the elastic solver uses human hair's defaults")
        return None
    values, unused = {}, []
    for attr in mprim.GetAuthoredAttributes():
        name = attr.GetName()
        if not name.startswith("physics:"):
            continue
        if name in READ:
            field, low, low_open, high = READ[name]
            value = attr.Get()
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise UserError(f"{mwhere}: {name} = {shown(value)}: expected a number")
            value = float(value)
            bad = not math.isfinite(value) or value < low or (low_open and value == low) or value > high
            if bad:
                lo = f"> {low:g}" if low_open else f">= {low:g}"
                rng = lo if high == math.inf else f"in ({low:g}, {high:g}]"
                raise UserError(f"{mwhere}: {name} = {value:g}: must be a finite number {rng}")
            values[field] = value
        elif name in UNUSED:
            unused.append(f"{name} ({UNUSED[name]})")
        else:
            close = difflib.get_close_matches(name, [*READ, *UNUSED], n=1, cutoff=0.8)
            if close:
                raise UserError(f"{mwhere}: unknown attribute {name} (did you mean {close[0]}?)")
            unused.append(f"{name} (not used by the elastic solver)")
    if unused and path not in seen:
        seen.add(path)
        warnings.append(f"{mwhere}: ignored: {', '.join(unused)}")
    return CurveMaterial(path=path, **values)


def read_rest_points(prim, code, n_points: int, where: str, warnings: list) -> np.ndarray | None:
    """``physics:restShapePoints`` (N, 3) local, stage units, when authored (None otherwise)."""
    ignored = [n for n in ("physics:restNormals", "physics:masses")
               if prim.GetAttribute(n) and prim.GetAttribute(n).HasAuthoredValue()]
    if ignored:
        warnings.append(f"{where}: ignored: {', '.join(ignored)} (the elastic solver's frames start untwisted "
                        "and its masses come from the density and widths)")
    attr = prim.GetAttribute("physics:restShapePoints")
    if not attr or not attr.HasAuthoredValue():
        return None
    raw = attr.Get(code)
    rest = np.array(raw if raw is not None else [], dtype=np.float64).reshape(-1, 3)
    if rest.shape[0] != n_points:
        raise UserError(f"{where}: physics:restShapePoints has {rest.shape[0]} points, expected {n_points} "
                        "(one per vertex)")
    bad = ~np.isfinite(rest).all(axis=1)
    if bad.any():
        raise UserError(f"{where}: physics:restShapePoints[{int(np.argmax(bad))}] is not finite")
    return rest


def read_bend_scale(prim, code, counts, n_points: int, ctype, basis, wrap, where: str) -> np.ndarray | None:
    """``primvars:dftl:bendStiffnessScale`` as one value per vertex (None when not authored)."""
    from pxr import UsdGeom

    pv = UsdGeom.PrimvarsAPI(prim).GetPrimvar(BEND_SCALE_PRIMVAR)
    if not pv or not pv.HasAuthoredValue():
        return None
    interp = str(pv.GetInterpolation())
    raw = curve_checks.flattened(pv, code, where)
    if raw is None or isinstance(raw, (str, bool)):
        raise UserError(f"{where}: primvars:{BEND_SCALE_PRIMVAR} = {shown(raw)}: expected numbers")
    try:
        values = np.asarray(raw, dtype=np.float64).reshape(-1)
    except (TypeError, ValueError):
        raise UserError(f"{where}: primvars:{BEND_SCALE_PRIMVAR}: expected numbers") from None
    if interp in ("varying", "faceVarying") and ctype == "cubic":
        raise UserError(f"{where}: primvars:{BEND_SCALE_PRIMVAR}: use vertex, uniform or constant "
                        "interpolation on cubic curves")
    v = curve_checks.check_primvar(values, interp, counts, n_points, ctype, basis, wrap,
                                   f"primvars:{BEND_SCALE_PRIMVAR}", where, nonnegative=True).reshape(-1)
    counts = np.asarray(counts, dtype=np.int64)
    if interp == "constant":
        return np.full(n_points, v[0])
    if interp == "uniform":
        return np.repeat(v, counts)
    return v.copy()
