"""Guides in a simulated scene (issue 22, docs/guides.md): which prims are simulated, and the render
curves deformed from them each frame.

Two ways a scene gets render curves:

- ``rel dftl:guides`` on a BasisCurves prim (:mod:`dftl_warp.usd.guides`): the prim is a render prim,
  deformed from the named guide prims, which are simulated as usual;
- ``simulate --guides N|FRACTION`` (:func:`parse_count`): from every prim without the relationship
  (a dense groom) ``N`` strands are picked (:func:`~dftl_warp.guides.select.select_guides`) and
  simulated as a prim of their own; the whole prim is then deformed from them, its guide strands
  reproduced exactly.

The binding is computed once, at the first frame, in **world space** (each prim's points through its
local-to-world transform at that frame); each frame the simulated guides go to world space, the
render points are deformed on the simulation's device (:class:`~dftl_warp.guides.deform.GuideDeformer`)
and come back to the render prim's local space. Velocities of deformed curves are the **backward
difference** of their local points over the previous sampled frame (zero at the first frame).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ..errors import UserError, plural
from ..usd.scene import CurvesPrim, Scene, transform_points
from ..core.layout import zero_length_segment
from .binding import bind, bind_groom, check_strands, pin_roots
from .select import METHODS, fraction_strands, select_guides

#: what ``--guides-output`` writes
OUTPUTS = ("curves", "binding")
#: suffix of the prim the guides picked from a dense prim are written to (``--guides-output binding``)
GUIDES_SUFFIX = "_guides"


def parse_count(text):
    """``--guides``: ``"10"`` -> 10 guides, ``"0.1"`` or ``"10%"`` -> the fraction 0.1."""
    if isinstance(text, (int, float)) and not isinstance(text, bool):
        value = text
    else:
        t = str(text).strip()
        from ..options import OPTIONS

        if not OPTIONS["guides"].pattern.match(t.replace(" ", "")):   # -3, nan, 1e-9, '': not a count
            raise UserError(f"--guides {text}: expected a number of guides, a fraction or a percentage (such as 10, "
                            "0.1 or 10%)")
        try:
            value = float(t[:-1]) / 100.0 if t.endswith("%") else (int(t) if t.isdigit() else float(t))
        except ValueError:
            raise UserError(f"--guides {text}: expected a number of guides, a fraction or a percentage") from None
    if isinstance(value, int):
        if value < 1:
            raise UserError(f"--guides {text}: at least 1 guide")
    elif not 0.0 < value <= 1.0:
        raise UserError(f"--guides {text}: a fraction must be in (0, 1] (a percentage in (0%, 100%])")
    return value


def check_guides_output(scene: Scene, guides: dict, cli: bool = False) -> None:
    """``guides_output`` asked for where no prim is guide-driven (no ``guides`` count, no ``rel
    dftl:guides``) was ignored without a word: ``binding`` raises a UserError naming ``scene``'s file
    (the output would hold no binding), ``curves`` (written anyway) adds a line to
    ``scene.warnings``. ``cli``: name the flags (``--guides-output``), else the keywords."""
    what = guides.get("guides_output")
    if what is None or guides.get("guides") is not None or any(c.guides for c in scene.curves):
        return
    output, count = ("--guides-output", "--guides") if cli else ("guides_output", "guides")
    why = (f"no prim here is driven by guides (give {count} N|FRACTION to pick them from each prim, or author "
           "rel dftl:guides on the render prims)")
    if what == "binding":
        raise UserError(f"{scene.source}: {output} binding: {why}")
    scene.warnings.append(f"{output} {what} does nothing: {why}")


def _subset(c: CurvesPrim, strands: np.ndarray, path: str) -> CurvesPrim:
    """The strands ``strands`` of ``c`` as a prim of their own (same transform and settings)."""
    starts = np.concatenate([[0], np.cumsum(c.counts)[:-1]])
    verts = np.concatenate([np.arange(starts[s], starts[s] + c.counts[s]) for s in strands])
    widths, interp = c.widths, c.widths_interpolation
    if widths is not None:
        if interp == "vertex" and widths.shape[0] == c.num_points:
            widths = widths[verts]
        elif interp == "uniform" and widths.shape[0] == c.num_strands:
            widths = widths[strands]
        elif interp != "constant":
            widths, interp = None, ""
    return replace(
        c, path=path, points=c.points[verts], counts=c.counts[strands], widths=widths, widths_interpolation=interp,
        display_color=None, display_color_interpolation="",
        rest_points=None if c.rest_points is None else c.rest_points[verts],
        bend_scale=None if c.bend_scale is None else c.bend_scale[verts], guides=())


@dataclass
class _Render:
    """One deformed output prim."""

    index: int  # in the output scene
    sources: list  # simulated prim indices whose points, in order, are the binding's guides
    binding: object
    deformer: object = None
    prev: tuple | None = None  # (frame, local points float32)
    #: (R, 3) the render roots in the prim's local space, where its transform holds them (None: roots
    #: bound to a dftl:rootMesh, left where the guides' frames put them)
    roots: np.ndarray | None = None


class GuideSet:
    """The guide plan of a scene: :attr:`sim_scene` (what is simulated), :attr:`output_scene` (what
    is written) and the render prims deformed each frame (:meth:`samples`)."""

    def __init__(self, scene: Scene, frame: int, *, guides=None, guide_method: str | None = None,
                 guides_output: str | None = None, k: int = 4):
        method = guide_method or "kmeans"
        output = guides_output or "curves"
        if method not in METHODS:
            raise UserError(f"--guide-method {method}: choose one of {', '.join(METHODS)}")
        if output not in OUTPUTS:
            raise UserError(f"--guides-output {output}: choose one of {', '.join(OUTPUTS)}")
        count = None if guides is None else parse_count(guides)
        self.method, self.output, self.count = method, output, count
        file = scene.source
        sim, sim_index = [], {}  # simulated prims, path -> index in sim
        picked = {}  # output index -> (sim index, strand indices) of a dense prim
        #: simulated prim index -> the input strand of each of its strands, for guides picked from a
        #: dense prim and simulated under its path (``curves`` output): messages name the input's strand
        self.input_strands: dict[int, np.ndarray] = {}
        for i, c in enumerate(scene.curves):
            if c.guides:
                continue
            if count is None:
                sim_index[c.path] = len(sim)
                sim.append(c)
                continue
            world = transform_points(c.transform(frame), c.points)
            try:
                check_strands(world, c.counts)
                chosen = select_guides(world, c.counts, count, method)
            except ValueError as exc:
                raise UserError(f"{file}: {c.path}: --guides {guides}: {_why(exc, c)}") from None
            if isinstance(count, float) and fraction_strands(count, c.num_strands) < 1:
                scene.warnings.append(f"{file}: {c.path}: --guides {guides} of its "
                                      f"{plural(c.num_strands, 'strand')} is "
                                      f"{count * c.num_strands:.3g} strands: 1 guide simulated")
            path = c.path + GUIDES_SUFFIX if output == "binding" else c.path
            picked[i] = (len(sim), np.asarray(chosen, dtype=np.int64))
            if output == "curves":
                self.input_strands[len(sim)] = picked[i][1]
            sim_index[c.path] = len(sim)
            sim.append(_subset(c, chosen, path))
        if output == "binding" and picked:
            _check_free(file, [sim[s].path for s, _ in picked.values()])
        self.sim_scene = replace(scene, curves=sim)
        self.renders: list[_Render] = []
        for i, c in enumerate(scene.curves):
            where = f"{file}: {c.path}"
            m = c.transform(frame)
            if i in picked:
                s, chosen = picked[i]
                _check_guide_segments(file, sim[s], chosen=chosen)
                try:
                    b = bind_groom(transform_points(m, c.points), c.counts, chosen, k=min(k, chosen.size))
                except ValueError as exc:
                    raise UserError(f"{where}: cannot bind to its guides: {exc}") from None
                self.renders.append(_Render(i, [s], b, roots=_local_roots(scene, c)))
            elif c.guides:
                sources = [sim_index[g] for g in c.guides]
                for s in sources:
                    _check_guide_segments(file, sim[s])
                gp = np.concatenate([transform_points(sim[s].transform(frame), sim[s].points) for s in sources])
                gc = np.concatenate([sim[s].counts for s in sources])
                try:
                    b = bind(gp, gc, transform_points(m, c.points), c.counts, k=min(k, gc.shape[0]))
                except ValueError as exc:
                    raise UserError(f"{where}: cannot bind to its guides {', '.join(c.guides)}: {exc}") from None
                self.renders.append(_Render(i, sources, b, roots=_local_roots(scene, c)))
        _warn_approximations(scene, self.renders)
        #: render prims' output indices -> _Render
        self._by_output = {r.index: r for r in self.renders}
        self._passthrough = {i: sim_index[c.path] for i, c in enumerate(scene.curves)
                             if not c.guides and i not in picked}
        self.input_scene = scene
        #: what the writer writes: every prim (deformed render curves as time samples), or the guides only
        self.output_scene = scene if output == "curves" else self.sim_scene
        self.tcps = scene.stage.time_codes_per_second

    @property
    def num_render_strands(self) -> int:
        return sum(r.binding.num_render for r in self.renders)

    def notes(self) -> list[str]:
        g = sum(c.num_strands for c in self.sim_scene.curves)
        how = f"{self.method}, " if self.count is not None else ""
        return [f"guides: {plural(g, 'guide strand')} simulated, {plural(self.num_render_strands, 'render strand')} in "
                f"{plural(len(self.renders), 'prim')} deformed from them ({how}k <= 4, bound at the first frame in world "
                f"space; render velocities: backward difference)"]

    def reset(self) -> None:
        """Forget the previous frame (a restored state): the next velocities are zero."""
        for r in self.renders:
            r.prev = None

    def samples(self, sim, simulated: list, device) -> list:
        """Output samples from the simulated prims' ``simulated`` (local points, velocities)."""
        if self.output == "binding":
            return simulated
        frame = sim.frame
        scene = self.input_scene
        out: list = [None] * len(scene.curves)
        for i, s in self._passthrough.items():
            out[i] = simulated[s]
        world = {}
        for r in self.renders:
            if r.deformer is None:
                from .deform import GuideDeformer

                r.deformer = GuideDeformer(r.binding, device=device)
            for s in r.sources:
                if s not in world:
                    m = sim.scene.curves[s].transform(frame)
                    world[s] = transform_points(m, np.asarray(simulated[s][0], dtype=np.float64))
            gp = np.concatenate([world[s] for s in r.sources])
            points = r.deformer.deform_numpy(gp)
            c = scene.curves[r.index]
            local = transform_points(np.linalg.inv(c.transform(frame)), points)
            if r.roots is not None:   # the roots stay where the prim holds them (docs/guides.md)
                local = pin_roots(local, r.binding, r.roots)
            local = local.astype(np.float32)
            if r.prev is None or r.prev[0] >= frame or sim._at_rest:
                vel = np.zeros_like(local)
            else:
                vel = ((local - r.prev[1]) * (self.tcps / (frame - r.prev[0]))).astype(np.float32)
            r.prev = (frame, local)
            out[r.index] = (local, vel)
        return out

    def write_binding(self, layer) -> None:
        """``--guides-output binding``: author on ``layer`` (the output writer's Sdf.Layer, before its
        commit saves it and moves it into place: the output is never changed after) each render
        prim's binding as primvars (docs/guides.md) and, for guides picked from a dense prim, the guide
        prim's topology (a BasisCurves prim ``<prim>_guides`` of purpose ``guide``: the render prim
        holds the same strands, and renderers draw guides only when asked to)."""
        from pxr import Sdf, Vt

        scene = self.input_scene
        for c in self.sim_scene.curves:
            if not c.path.endswith(GUIDES_SUFFIX) or layer.GetPrimAtPath(c.path) is None:
                continue
            spec = layer.GetPrimAtPath(c.path)
            spec.specifier = Sdf.SpecifierDef
            spec.typeName = "BasisCurves"
            _attr(spec, "curveVertexCounts", Sdf.ValueTypeNames.IntArray, Vt.IntArray([int(n) for n in c.counts]), True)
            _attr(spec, "type", Sdf.ValueTypeNames.Token, c.type, True)
            _attr(spec, "basis", Sdf.ValueTypeNames.Token, c.basis, True)
            _attr(spec, "wrap", Sdf.ValueTypeNames.Token, c.wrap, True)
            # they are strands of the render prim too: drawn only where guides are asked for (not twice)
            _attr(spec, "purpose", Sdf.ValueTypeNames.Token, "guide", True)
            if c.widths is not None:
                a = _attr(spec, "widths", Sdf.ValueTypeNames.FloatArray, Vt.FloatArray([float(w) for w in c.widths]))
                a.SetInfo("interpolation", c.widths_interpolation or "constant")
        for r in self.renders:
            c = scene.curves[r.index]
            b = r.binding
            spec = layer.GetPrimAtPath(c.path) or Sdf.CreatePrimInLayer(layer, c.path)
            if spec.specifier != Sdf.SpecifierDef:
                spec.specifier = Sdf.SpecifierOver
            guides = [self.sim_scene.curves[s].path for s in r.sources]
            rel = spec.relationships.get("dftl:guides") or Sdf.RelationshipSpec(spec, "dftl:guides", custom=True)
            rel.targetPathList.explicitItems = [Sdf.Path(p) for p in guides]
            k = b.k
            for name, tname, values, interp, elem in (
                ("primvars:dftl:guideIds", Sdf.ValueTypeNames.IntArray,
                 Vt.IntArray([int(x) for x in b.guide_ids[:, :k].reshape(-1)]), "uniform", k),
                ("primvars:dftl:guideWeights", Sdf.ValueTypeNames.FloatArray,
                 Vt.FloatArray([float(x) for x in b.weights[:, :k].reshape(-1)]), "uniform", k),
                ("primvars:dftl:guideOffsets", Sdf.ValueTypeNames.Vector3fArray,
                 Vt.Vec3fArray.FromNumpy(np.ascontiguousarray(b.offsets.reshape(b.t.shape[0], -1)[:, :3], dtype=np.float32))
                 if b.frames == "blend" else None, "vertex", 1),
                ("primvars:dftl:guideParam", Sdf.ValueTypeNames.FloatArray,
                 Vt.FloatArray([float(x) for x in b.t]), "vertex", 1),
            ):
                if values is None:
                    continue
                a = _attr(spec, name, tname, values)
                a.SetInfo("interpolation", interp)
                if elem > 1:
                    a.SetInfo("elementSize", elem)


def _attr(spec, name, type_name, value, uniform: bool = False):
    from pxr import Sdf

    a = spec.attributes.get(name) or Sdf.AttributeSpec(spec, name, type_name,
                                                         Sdf.VariabilityUniform if uniform else Sdf.VariabilityVarying)
    a.default = value
    return a


def _warn_approximations(scene: Scene, renders: list) -> None:
    """One warning per render prim for what its deformation approximates: strands that are not
    guides are not collided (40 strands of 30 cm draped over a ball of radius 15 cm in 24 frames end
    up to 63 mm inside it with 4 guides, 19 mm with 8, none when all are simulated), and a lone guide
    has nothing to fix its root normal, which turns as the guide bends (28 deg about its root tangent
    in one frame of falling), swinging the render strands around it."""
    colliders = ", ".join(c.path for c in scene.colliders)
    for r in renders:
        b, path = r.binding, scene.curves[r.index].path
        if not (b.render_guide < 0).any():
            continue
        if colliders:
            scene.warnings.append(f"{path}: its render strands are deformed from their guides, not collided: they may "
                                  f"end inside {colliders} (more guides bring them closer to the guides' contacts)")
        if b.num_guides == 1:
            scene.warnings.append(f"{path}: its render strands follow one guide: nothing fixes that guide's twist, so "
                                  "they turn about its root as it bends; give it 2 or more guides")


def _check_free(file: str, paths: list) -> None:
    """``--guides-output binding`` defines a prim ``<prim>_guides`` for the guides picked from each
    dense prim: one already on the stage (any type) would be overwritten; refused, naming it."""
    from pxr import Usd

    stage = Usd.Stage.Open(str(file), Usd.Stage.LoadNone)
    for path in paths:
        if stage.GetPrimAtPath(path):
            raise UserError(f"{file}: {path}: already exists; --guides-output binding writes the guides picked from "
                            f"{path.removesuffix(GUIDES_SUFFIX)} there: rename or remove it")


def _local_roots(scene: Scene, c: CurvesPrim):
    """The roots of ``c``'s render strands in its local space (they follow its transform), or None
    for roots bound to a ``dftl:rootMesh``: those follow the guides' root frames, with one warning."""
    if c.root_mesh is None:
        return np.asarray(c.points[c.root_indices], dtype=np.float64)
    scene.warnings.append(f"{c.path}: roots bound to dftl:rootMesh: the render strands' roots follow their guides' "
                          "root frames, not the mesh (they may drift off it by up to a guide spacing)")
    return None


def _check_guide_segments(file: str, guide: CurvesPrim, chosen=None) -> None:
    """Refuse (one line naming file, prim, curve and points) a guide curve with two consecutive
    coincident points: no frame there, so the render strands bound to it could not keep their rest
    shape. ``chosen``: the guide prim is those strands of a dense prim (named by their index there)."""
    found = zero_length_segment(guide.points, guide.counts)
    if found is None:
        return
    k, i = found
    path, curve = (guide.path, k) if chosen is None else (guide.path.removesuffix(GUIDES_SUFFIX), int(chosen[k]))
    picked = "" if chosen is None else " (picked as a guide by --guides)"
    raise UserError(f"{file}: {path}: curve {curve}{picked}: points {i} and {i + 1} coincide (a zero-length "
                    "segment): a guide needs non-zero segments to carry its render strands; remove the repeated "
                    "point")


def _why(exc: ValueError, c: CurvesPrim) -> str:
    text = str(exc)
    if "asks for" in text:
        return f"{text.replace('n_or_fraction asks for', 'asks for')} (the prim has {plural(c.num_strands, 'strand')})"
    return text
