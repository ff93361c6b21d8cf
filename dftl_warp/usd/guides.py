"""``rel dftl:guides`` (issue 22, docs/guides.md): a render BasisCurves prim names the guide
BasisCurves prim(s) it follows. Render prims are not simulated: their guides are, and the render
curves are deformed from them (:mod:`dftl_warp.guides.scene`).

Checked here, each problem one line naming the file and the prim (:class:`UserError`, exit 2): a
target that is missing, inactive or not a BasisCurves prim, a prim naming itself, a guide prim that itself
names guides, and a render prim whose own ``dftl:`` solver settings differ from its guides'.
"""

from __future__ import annotations

from ..errors import UserError

#: the relationship's name
RELATIONSHIP = "dftl:guides"


def read_guide_paths(prim, file: str) -> tuple:
    """The targets of ``prim``'s ``dftl:guides`` relationship (paths as text, in order), each a
    BasisCurves prim; () when the prim has none."""
    from pxr import UsdGeom

    where = f"{file}: {prim.GetPath()}"
    rel = prim.GetRelationship(RELATIONSHIP)
    if not rel or not rel.HasAuthoredTargets():
        return ()
    targets = rel.GetForwardedTargets()
    if not targets:
        raise UserError(f"{where}: {RELATIONSHIP} has no targets; expected one or more BasisCurves prims")
    stage = prim.GetStage()
    out = []
    for t in targets:
        if t == prim.GetPath():
            raise UserError(f"{where}: {RELATIONSHIP} -> {t}: a prim cannot be its own guide")
        target = stage.GetPrimAtPath(t)
        if not target:
            raise UserError(f"{where}: {RELATIONSHIP} -> {t}: no such prim")
        if not target.IsActive():   # inactive hair prims are not simulated: nor is an inactive guide
            raise UserError(f"{where}: {RELATIONSHIP} -> {t}: the guide prim is inactive (active = false): activate "
                            f"it, or remove it from {RELATIONSHIP}")
        if not target.IsA(UsdGeom.BasisCurves):
            raise UserError(f"{where}: {RELATIONSHIP} -> {t}: not a BasisCurves prim ({target.GetTypeName() or 'untyped'})")
        if str(t) not in out:
            out.append(str(t))
    return tuple(out)


def check_guides(curves, file: str) -> None:
    """Render prims (``guides`` set) against their guides among ``curves`` (CurvesPrim list)."""
    by_path = {c.path: c for c in curves}
    for c in curves:
        if not c.guides:
            continue
        where = f"{file}: {c.path}"
        for g in c.guides:
            guide = by_path.get(g)
            if guide is None:
                raise UserError(f"{where}: {RELATIONSHIP} -> {g}: the guide prim is not simulated (empty, "
                                f"dftl:simulate = false, or under an instanceable prim)")
            if guide.guides:
                raise UserError(f"{where}: {RELATIONSHIP} -> {g}: that prim names guides itself "
                                f"({guide.guides[0]}); guides must be simulated prims")
            if c.root_mesh is not None:
                raise UserError(f"{where}: dftl:rootMesh on a render prim: bind its guides' roots instead")
            for name in ("solver", "damping", "correction", "substeps", "inverse_statics", "bending"):
                mine, theirs = getattr(c.settings, name), getattr(guide.settings, name)
                if mine is not None and mine != theirs:
                    raise UserError(
                        f"{where}: dftl:{_usd_name(name)} = {mine!r} on a render prim conflicts with its guide {g} "
                        f"({'unset' if theirs is None else repr(theirs)}): render prims are not simulated; set it on "
                        f"the guide prim")
        if c.features:
            names = ", ".join(sorted(c.features))
            raise UserError(f"{where}: {names} on a render prim: render prims are not simulated; set it on the "
                            f"guide prim(s)")


def _usd_name(name: str) -> str:
    from ..options import OPTIONS

    return OPTIONS[name].usd.split(":", 1)[1]
