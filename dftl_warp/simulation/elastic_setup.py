"""What a simulation group passes to the elastic solver (``solver = "elastic"``), from the Scene's
plain data, all in stage units (:mod:`dftl_warp.solvers.elastic_material` converts the defaults):

- the material of the group's prims (one per group: the simulation groups prims by bound material);
- the radius: half the widths per point (the solver's 40 um, in stage units, where a prim has none);
- the stiffness scale per point: ``primvars:dftl:bendStiffnessScale`` times what an authored
  ``physics:curvesBendStiffness`` (E*I) needs;
- the rest shape: ``physics:restShapePoints`` through the prim's transform, where authored;
- ``dftl:inverseStatics``; a uniform ``dftl:drag`` (without wind) becomes the solver's implicit drag.

The rest shape must have no zero-length segment (:func:`check_rest_lengths`: one line naming the
file, prim, curve and segment, checked before the solver is built; ``dftl-warp info`` checks it too).

And the clamp (:class:`ClampDriver`): each strand's authored ghost point in its prim's local space,
moved every frame by the same matrices as the roots.
"""

from __future__ import annotations

import numpy as np

from ..core.layout import zero_length_segment  # noqa: F401  (also imported from here)
from ..errors import UserError, plural
from ..features import Drag, find
from ..solvers.elastic_material import default_radius, stage_material
from ..usd.scene import transform_points


def material_key(curve):
    """The part of a prim's grouping key its material decides (prims of one group share one)."""
    return None if curve.material is None else curve.material.path


def _note(scene, text: str) -> None:
    line = f"{scene.source}: {text}"
    if line not in scene.warnings:
        scene.warnings.append(line)


def check_rest_lengths(source: str, curve, points, solver: str = "elastic") -> None:
    """Refuse (:class:`UserError`) a prim whose rest shape ``points`` (its authored points, or its
    ``physics:restShapePoints``) has a zero-length segment: the elastic solver needs non-zero rest
    lengths (its bending and twist are per unit length), as do ``rattle`` and ``reference`` (their
    constraint directions). One line naming file, prim, curve and segment (0-based, within the
    prim) and what to do."""
    found = zero_length_segment(points, curve.counts)
    if found is None:
        return
    k, i = found
    what = "physics:restShapePoints" if curve.rest_points is not None else "points"
    raise UserError(f"{source}: {curve.path}: curve {k}, segment {i}: {what} {i} and {i + 1} of the curve "
                    f"coincide (a zero-length segment); the {solver} solver needs non-zero rest lengths: remove "
                    "the coincident points, or use --solver dftl (or dftl:solver = \"dftl\"), which simulates them")


def elastic_options(scene, curves, frame, features, widths, settings) -> tuple[dict, list]:
    """(make_solver keywords, the features left for the Model) of a group of ``curves``."""
    info = scene.stage
    mat = stage_material(curves[0].material, info.meters_per_unit, info.kilograms_per_unit)
    for note in mat.notes:
        _note(scene, note)
    r0 = default_radius(info.meters_per_unit)
    radius, scale, rest, any_rest = [], [], [], False
    offset = 0
    for c in curves:
        n = c.num_points
        w = None if widths is None else widths[offset:offset + n]
        offset += n
        if w is None or not np.any(w > 0):
            _note(scene, f"{c.path}: no widths: the elastic solver uses a 40 um hair radius")
            r = np.full(n, r0)
        else:
            if c.widths is not None and c.widths.size not in (1, c.num_points, c.num_strands):
                _note(scene, f"{c.path}: {c.widths_interpolation} widths on cubic curves: the elastic solver "
                             "uses their mean")
            if np.any(w <= 0):
                _note(scene, f"{c.path}: zero widths: the elastic solver uses a 40 um hair radius there")
            r = np.where(w > 0, 0.5 * w, r0)
        radius.append(r)
        s = mat.bend_scale(r) * (1.0 if c.bend_scale is None else c.bend_scale)
        scale.append(np.broadcast_to(s, (n,)))
        m = c.transform(frame)
        check_rest_lengths(scene.source, c, c.points if c.rest_points is None else c.rest_points)
        if c.rest_points is not None:
            any_rest = True
            rest.append(transform_points(m, c.rest_points))
        else:
            rest.append(transform_points(m, c.points))
    kwargs = dict(youngs_modulus=mat.youngs_modulus, density=mat.density, radius=np.concatenate(radius),
                  twist_modulus=mat.twist_modulus(np.concatenate(radius)),
                  stiffness_scale=np.concatenate(scale), inverse_statics=settings.inverse_statics)
    if any_rest:
        kwargs["rest_shape"] = np.concatenate(rest)
    drag = find(features, Drag)
    if drag is not None and len(features) == 1:
        rate = np.unique(np.asarray(drag.rate, float))
        if rate.size == 1:
            kwargs["drag"] = float(rate[0])
            features = []
    return kwargs, features


def rotation_of(matrix: np.ndarray) -> np.ndarray:
    """The rotation (3x3, column vectors) of a 4x4 row-vector matrix's linear part: its polar factor
    (scale and shear left out)."""
    u, _, vt = np.linalg.svd(np.asarray(matrix, dtype=np.float64)[:3, :3].T)
    r = u @ vt
    if np.linalg.det(r) < 0:   # a mirroring matrix: the rotation nearest its proper part
        u[:, -1] = -u[:, -1]
        r = u @ vt
    return r


class ClampDriver:
    """Moves a group's clamp ghosts with its prims' transforms (a rotating clamp), and turns the
    root frames with them (about the first segment too)."""

    def __init__(self, group, frame: int):
        solver, curves = group.solver, group.curves
        ghosts = solver.authored_clamps                    # world, input strand order, at ``frame``
        self.local, self.rest_rotations, self.counts, k = [], [], [], 0
        for c in curves:
            g = ghosts[k:k + c.num_strands]
            k += c.num_strands
            self.local.append(transform_points(np.linalg.inv(c.transform(frame)), g))
            self.rest_rotations.append(rotation_of(c.transform(frame)))
            self.counts.append(c.num_strands)

    def world(self, matrix_of, members, frame: int) -> np.ndarray:
        """Ghosts (S, 3) world at ``frame``; ``matrix_of(index, frame)`` gives a prim's matrix."""
        return np.concatenate([transform_points(matrix_of(i, frame), g) for i, g in zip(members, self.local)])

    def prim_rotations(self, matrix_of, members, frame: int) -> np.ndarray:
        """Each prim's clamp rotation (P, 3, 3) at ``frame`` from its authored pose: its rotation
        then, times the inverse of its rotation when the group was made."""
        return np.stack([rotation_of(matrix_of(i, frame)) @ r0.T for i, r0 in zip(members, self.rest_rotations)])

    def rotations(self, matrix_of, members, frame: int) -> np.ndarray:
        """Each strand's clamp rotation (S, 3, 3) at ``frame`` (its prim's: :meth:`prim_rotations`)."""
        return np.repeat(self.prim_rotations(matrix_of, members, frame), self.counts, axis=0)


def rest_where_moved(group, frame: int) -> list[str]:
    """After the clean start moved hair out of a collider: the elastic strands it moved rest where
    they are (their authored shape lay inside, and as the rest shape it would press them back in at
    every step: a chatter that never settles, docs/elastic.md); strands of prims with authored
    ``physics:restShapePoints`` keep theirs. The group's clamps follow the new rest shape. Returns
    the notes to print (none when nothing moved)."""
    solver = group.solver
    explicit = np.concatenate([np.full(c.num_strands, c.rest_points is not None) for c in group.curves])
    moved = solver.moved_strands(group.state)
    kept = moved[explicit[moved]]
    adopted = solver.adopt_rest_shape(group.state, strands=moved[~explicit[moved]])
    notes = []
    if adopted.size:
        group.clamps = ClampDriver(group, frame)
        one = adopted.size == 1
        notes.append(f"clean start: {plural(adopted.size, 'elastic strand')} {'rests' if one else 'rest'} where "
                     f"{'it was' if one else 'they were'} moved out ({'its' if one else 'their'} authored shape lay "
                     "inside the collider)")
    if kept.size:
        one = kept.size == 1
        notes.append(f"clean start: {plural(kept.size, 'elastic strand')} with authored physics:restShapePoints "
                     f"started inside a collider and {'keeps its' if one else 'keep their'} rest shape, which presses "
                     f"{'it' if one else 'them'} into it")
    return notes


def note_unstable(scene, group) -> None:
    """A note when strands of the group rest in an unstable equilibrium for their stiffness
    (:func:`~dftl_warp.solvers.elastic_stability.unstable_strands`: standing beyond their buckling
    length); inverse statics holds them only until round-off tips them over. And one when the
    authored shape needs a bend where ``primvars:dftl:bendStiffnessScale`` is 0 (:func:`note_unheld`)."""
    if not group.solver.inverse_statics:
        return
    note_unheld(scene, group)
    untested = note_untested(scene, group)
    flagged, scales, tested, total = group.solver.unstable_strands()
    if flagged.size == 0:
        return
    of = (f"of the {plural(tested, 'strand')}" if tested == total else
          f"of the {plural(tested, 'strand')} checked" if tested + untested == total else
          f"of a random sample of {tested} of the {plural(total, 'strand')}")
    them = "of them" if scales.size == flagged.size else f"of a random sample of {scales.size} of them"
    rest = "rests" if flagged.size == 1 else "rest"
    _note(scene, f"{_prims(group, flagged)}: {flagged.size} {of} {rest} in an unstable equilibrium for hair this "
                 "stiff (standing beyond their buckling length, or held by their twist, docs/elastic.md) and can "
                 f"fall at the first disturbance; {_holding(scales, them, group.solver.stiffness_scale)}")


def note_untested(scene, group) -> int:
    """A note naming the strands too long for the stability test's budget
    (:meth:`~dftl_warp.solvers.elastic.ElasticSolver.unchecked_strands`): nothing is said about whether they
    can stand, and a long curl held by inverse statics can be unstable (curls of 80 um hair, 4 mm
    radius, 3 mm pitch: the check, run without a budget, flags those of 450 points and more; one of
    1500 points hanging from a still root flails at 16-58 m/s from its third frame). Returns how
    many strands it names."""
    from ..solvers.elastic_stability import longest_tested

    long, most = group.solver.unchecked_strands()
    if long.size:
        _note(scene, f"{_prims(group, long)}: {plural(long.size, 'strand')} of more than {longest_tested()} segments "
                     f"(up to {most}) {'was' if long.size == 1 else 'were'} "
                     "not checked for a stable rest shape (the check's cost grows as the cube of the segments): "
                     "a long curl or a standing strand held by inverse statics may fall at the first disturbance "
                     "unannounced; resample them to fewer points to have them checked")
    return int(long.size)


def _prims(group, strands) -> str:
    """The prims (up to 3, then a count) of the group's input ``strands``."""
    owner = np.repeat(np.arange(len(group.curves)), [c.num_strands for c in group.curves])
    prims = [group.curves[i].path for i in np.unique(owner[strands])]
    return ", ".join(prims[:3]) + (f" and {plural(len(prims) - 3, 'more prim')}" if len(prims) > 3 else "")


def _holding(scales, them: str, authored=None) -> str:
    """What stiffness holds the unstable strands of the sample ``scales`` (factors on the authored
    stiffness; inf: a strand standing on a vertex of scale 0, which no factor stiffens). ``authored``:
    the group's ``primvars:dftl:bendStiffnessScale`` per point; one value everywhere, the line gives
    the value to author (the factor times it), else the factor on the authored ramp, and says so."""
    authored = np.ones(1) if authored is None else np.asarray(authored, float)
    one = authored.size == 0 or bool(np.all(authored == authored.flat[0]))
    base = float(authored.flat[0]) if one and authored.size else 1.0
    scale = "primvars:dftl:bendStiffnessScale"
    what = f"{scale} of" if one else f"a factor on the authored {scale} of"
    hinged = int(np.isinf(scales).sum())
    if not hinged:
        if scales.size == 1:   # one strand: no half of them
            return f"{what} {scales.max() * base:.3g} holds it"
        return f"{what} {np.median(scales) * base:.3g} holds half {them}, {scales.max() * base:.3g} all"
    text = f"no {scale} holds {hinged} {them}: they stand on a vertex of scale 0"
    if hinged < scales.size:
        held = scales[np.isfinite(scales)] * base
        text += f"; {np.median(held):.3g} holds half the others, {held.max():.3g} all"
    return text


def note_unheld(scene, group) -> None:
    """A note when the authored shape needs a bending moment at vertices whose
    ``primvars:dftl:bendStiffnessScale`` is 0 (no bending stiffness: a hinge), which inverse
    statics cannot give: the hair bends there under gravity from the first frame."""
    strands, vertices = group.solver.unheld_vertices()
    if strands.size == 0:
        return
    _note(scene, f"{_prims(group, strands)}: {plural(vertices, 'vertex', 'vertices')} of "
                 f"{plural(strands.size, 'strand')} "
                 f"{'has' if vertices == 1 else 'have'} "
                 "primvars:dftl:bendStiffnessScale 0 (no bending stiffness) where the authored shape is bent "
                 "under its weight: inverse statics cannot hold it, so the hair bends there from the first frame")
