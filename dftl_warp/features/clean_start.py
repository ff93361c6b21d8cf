"""Clean starts: hair that starts inside a collider is moved out before the first frame, and the
groom can settle at the first frame's pose (a preroll) before the shot.

- :func:`measure_start`: how many particles (roots excluded) start inside a collider and how deep
  (:class:`StartReport`, with its one-line :meth:`StartReport.line`);
- :func:`resolve_start`: moves them out along the shortest path (the collider's outward normal:
  the gradient of its signed distance), then re-projects each strand to its rest lengths from the
  root, as follow-the-leader does, colliding again after each projection; a few rounds. Mesh
  colliders are queried here to any depth (the step's ``depth_band`` does not apply);
- :func:`still_inside` and :func:`inside_note`: the particles the push-out could not free, and
  their one line;
- :func:`preroll`: ``seconds`` of simulation with the roots and colliders held where the control
  puts them (the caller sets the first frame's pose, start = end), velocities damped every frame,
  going on (up to 8x ``seconds``) until no particle moves more than the settling tolerance over a
  frame, then zeroed, so the shot starts settled and at rest (:class:`PrerollReport`).

Every registered collider shape is covered: the kernels (``kernels/features/clean_start.py``)
reuse the shapes' collide functions.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import warp as wp

from ..errors import plural
from ..kernels.features.clean_start import motion_kernel, penetration_kernel, resolve_kernel, scale_velocities_kernel
from ..kernels.features.collide import collider_flags
from ..kernels.features.step import feature_struct


@dataclass
class StartReport:
    """Particles (roots excluded) of a state against the colliders: ``inside`` below a collider's
    surface, ``touching`` within the contact distance (hair radius; ``inside`` included);
    ``max_depth`` below the surface (m, or stage units), also in hair radii (``max_depth_radii``,
    0 when the hair has no width); ``max_penetration``: beyond the contact distance (m)."""

    particles: int
    inside: int
    touching: int
    max_depth: float
    max_depth_radii: float
    max_penetration: float
    max_penetration_radii: float

    def line(self, units: str = "m") -> str:
        if self.inside == 0:
            return f"clean start: no particle starts inside a collider ({self.particles} checked, roots excluded)"
        radii = f" ({self.max_depth_radii:.3g} hair radii)" if self.max_depth_radii > 0 else ""
        return (f"clean start: {self.inside} of {self.particles} free particles (roots excluded) started inside a "
                f"collider, up to "
                f"{self.max_depth:.3g} {units} deep{radii}; moved out along the shortest path")


def _flags(model) -> frozenset:
    return frozenset(model.feature_flags) & frozenset(collider_flags())


def _struct(model, control):
    """The colliders' step struct at the frame's start pose, meshes queried to any depth."""
    flags = _flags(model)
    Features = feature_struct(model.scalar, flags)
    st = Features()
    cc = control.features.colliders
    cc.advance(0.0)
    cc.advance(0.0)   # the current and previous substep poses both at the frame's start
    cc.fill_struct(st)
    keep = None
    meshes = cc.kind_data.get("meshes")
    if meshes is not None:
        span = float(np.linalg.norm(meshes.upper.numpy() - meshes.lower.numpy(), axis=1).max())
        keep = wp.full(meshes.depth_band.shape[0], 2.0 * span + 1.0, dtype=model.scalar, device=model.device)
        st.collider_depth_band = keep
    return Features, flags, st, keep


def _head(model):
    return [model.strand_base, model.strand_stride, model.strand_count]


def _depths(model, state, control):
    """Per device strand and particle 1.. (roots excluded): the distance each collider's response
    would move it, its hair radius, and which entries are particles."""
    Features, flags, st, keep = _struct(model, control)
    counts = model.strand_count.numpy()
    shape = (model.num_strands, int(counts.max()))
    pen = wp.zeros(shape, dtype=model.scalar, device=model.device)
    rad = wp.zeros(shape, dtype=model.scalar, device=model.device)
    wp.launch(penetration_kernel(model.scalar, Features, flags), dim=shape, device=model.device,
              inputs=[*_head(model), st, state.positions, pen, rad])
    pen, rad = pen.numpy().astype(np.float64)[:, 1:], rad.numpy().astype(np.float64)[:, 1:]
    return pen, rad, np.arange(1, shape[1])[None, :] < counts[:, None]


def _inside(model, pen, rad, valid):
    """Which entries of :func:`_depths` are inside a collider: deeper than their hair radius, and
    than a few units in the last place of the model's coordinates (hair without width moved onto a
    surface sits there to the arithmetic's round-off, which is no penetration: 1e-8 m on a float32
    head, which was named as hair still inside)."""
    rest = model.rest_positions
    extent = float(np.abs(rest).max()) if rest is not None and rest.size else 0.0
    floor = 8.0 * float(np.finfo(np.dtype(model.precision)).eps) * extent
    return valid & (pen > np.maximum(rad, floor))


def measure_start(model, state, control) -> StartReport:
    """How many particles of ``state`` are inside the colliders at ``control``'s frame-start pose."""
    if control.features is None or control.features.colliders is None:
        return StartReport(model.num_points - model.num_strands, 0, 0, 0.0, 0.0, 0.0, 0.0)
    pen, rad, valid = _depths(model, state, control)
    inside = _inside(model, pen, rad, valid)
    touching = valid & (pen > 0)
    depth = np.where(inside, pen - rad, 0.0)
    excess = np.where(touching, pen, 0.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        depth_r = np.where(inside & (rad > 0), depth / rad, 0.0)
        excess_r = np.where(touching & (rad > 0), excess / rad, 0.0)
    return StartReport(int(valid.sum()), int(inside.sum()), int(touching.sum()), float(depth.max(initial=0.0)),
                       float(depth_r.max(initial=0.0)), float(excess.max(initial=0.0)),
                       float(excess_r.max(initial=0.0)))


def resolve_start(model, state, control, *, iterations: int = 4, rounds: int = 8,
                  tolerance: float = 1.0e-3, inside_only: bool = False) -> StartReport:
    """Move the particles of ``state`` that are inside the colliders (at ``control``'s frame-start
    pose) out along the shortest path and back onto their rest lengths from the root; up to
    ``rounds`` sweeps, until no particle penetrates the contact distance by more than
    ``tolerance`` hair radii. Returns the report of the state as it was (before). With
    ``inside_only``, a state with no particle inside a collider (only within the contact distance:
    resting on it, which the step's own contact handles) is left as it is."""
    return resolve_parts([(model, state, control)], iterations=iterations, rounds=rounds, tolerance=tolerance,
                         inside_only=inside_only)


def combine_reports(reports) -> StartReport:
    """The report of a groom whose parts (split over devices) gave ``reports``."""
    if len(reports) == 1:
        return reports[0]
    return StartReport(*(sum(getattr(r, f) for r in reports) for f in ("particles", "inside", "touching")),
                       *(max(getattr(r, f) for r in reports) for f in ("max_depth", "max_depth_radii",
                                                                        "max_penetration", "max_penetration_radii")))


def resolve_parts(parts, *, iterations: int = 4, rounds: int = 8, tolerance: float = 1.0e-3,
                  inside_only: bool = False) -> StartReport:
    """:func:`resolve_start` of a groom held in ``parts`` ((model, state, control) of each device's
    strands), moved out as one: whether to move at all, and when the rounds stop, is decided on the
    whole groom's report, so a split groom ends exactly as on one device. Returns the whole groom's
    report before."""
    before = combine_reports([measure_start(m, st, c) for m, st, c in parts])
    if before.touching == 0 or (inside_only and before.inside == 0):
        return before
    sweeps = []
    for m, st, c in parts:
        Features, flags, struct, keep = _struct(m, c)
        sweeps.append((m, st, resolve_kernel(m.scalar, Features, flags), struct, keep))
    for _ in range(rounds):
        for m, st, kernel, struct, _ in sweeps:
            wp.launch(kernel, dim=m.num_strands, device=m.device,
                      inputs=[*_head(m), m.rest_lengths, struct, int(iterations), st.positions])
        after = combine_reports([measure_start(m, st, c) for m, st, c in parts])
        if after.touching == 0 or after.max_penetration_radii <= tolerance:
            break
    return before


def still_inside(model, state, control) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The particles of ``state`` (roots excluded) below a collider's surface at ``control``'s
    frame-start pose, deepest first: their input strand indices, their indices along the strand,
    their depths below the surface (m, or stage units) and their hair radii. After
    :func:`resolve_start` these are the particles it could not free: no point at the rest length
    from their leader is outside (a strand through a thin part, or folded in a concave one)."""
    empty = np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0), np.zeros(0)
    if control.features is None or control.features.colliders is None:
        return empty
    pen, rad, valid = _depths(model, state, control)
    s, i = np.nonzero(_inside(model, pen, rad, valid))
    depth = (pen - rad)[s, i]
    order = np.argsort(-depth, kind="stable")
    return model.layout.strand_order[s[order]], i[order] + 1, depth[order], rad[s, i][order]


def strand_name(prims, strand: int, path: bool = True) -> str:
    """``"<prim> strand <k>"`` for strand ``strand`` of a group whose prims are ``prims``: (path,
    number of strands) or (path, number of strands, the input strand of each: guides picked from a
    dense prim, None: the strands themselves) in order; ``path=False``: the prim's path left out
    where the group has one prim."""
    offsets = np.cumsum([0] + [p[1] for p in prims])
    p = int(np.searchsorted(offsets, strand, side="right")) - 1
    local = int(strand - offsets[p])
    ids = prims[p][2] if len(prims[p]) > 2 else None
    name = f"strand {local}" if ids is None else f"strand {int(ids[local])}"
    return name if not path and len(prims) == 1 else f"{prims[p][0]} {name}"


def inside_note(parts, prims, units: str = "m") -> str | None:
    """One line for the particles still inside a collider (:func:`still_inside`) in ``parts``
    ((model, state), control) pairs holding consecutive strands of a group, naming the deepest
    one's prim, strand and point; ``prims``: the group's prims (:func:`strand_name`). None when
    nothing is inside."""
    found, offset = [], 0
    for (model, state), control in parts:
        s, i, d, r = still_inside(model, state, control)
        found.append((s + offset, i, d, r))
        offset += model.num_strands
    strands, particles, depth, radius = (np.concatenate(a) for a in zip(*found))
    if len(strands) == 0:
        return None
    k = int(np.argmax(depth))
    radii = f" ({depth[k] / radius[k]:.3g} hair radii)" if radius[k] > 0 else ""
    verb = "is" if len(strands) == 1 else "are"
    return (f"clean start: {plural(len(strands), 'particle')} of {plural(len(np.unique(strands)), 'strand')} {verb} "
            f"still inside a "
            f"collider after moving out, up to {depth[k]:.3g} {units} deep{radii} at "
            f"{strand_name(prims, int(strands[k]))}, point {int(particles[k])}: no point at their rest lengths from "
            "the root is outside (a strand through a thin part of the collider, or folded inside it); they stay "
            "in until the motion throws them out: check the groom there")


def damp_velocities(model, state, factor: float) -> None:
    """Multiply every particle's velocity by ``factor``."""
    wp.launch(scale_velocities_kernel(model.scalar), dim=model.num_strands, device=model.device,
              inputs=[*_head(model), float(factor), state.velocities])


@dataclass
class PrerollReport:
    """What :func:`preroll` did: ``frames`` of ``frame_dt`` (``seconds`` in all), whether the groom
    ``settled`` (no particle moved more than ``tolerance`` over the last frame), and that frame's
    largest motion ``motion`` (m, or stage units)."""

    frames: int
    seconds: float
    settled: bool
    motion: float
    tolerance: float

    def line(self, units: str = "m") -> str:
        if self.frames == 0:
            return "preroll: none"
        state = "settled" if self.settled else "NOT settled"
        return (f"preroll: {self.seconds:.3g} s ({self.frames} frames) at the first frame's pose, {state}: "
                f"largest motion over the last frame {self.motion:.3g} {units} (tolerance {self.tolerance:.3g})")


def settle_tolerance(model, *more) -> float:
    """Largest motion per frame of a settled groom: the mean hair radius (motion below the contact
    distance, the scale of the contacts' own jitter, is not visible as a pop), else a thousandth of
    the mean strand length for hair without width. ``more``: further models holding the rest of
    the groom (a groom split over devices), counted with ``model``."""
    models = (model, *more)
    radii = []
    for m in models:
        data = getattr(m.feature_data, "collider_data", None)
        radius = None if data is None else data.arrays.get("particle_radius")
        if radius is not None:
            radii.append(radius.numpy().astype(np.float64))
    r = np.concatenate(radii) if len(radii) == len(models) else np.zeros(0)
    if r.size and float(r.max()) > 0:
        return float(r[r > 0].mean())
    lengths = sum(float(m.rest_lengths.numpy().astype(np.float64).sum()) for m in models)
    return 1.0e-3 * lengths / max(sum(m.num_strands for m in models), 1)


def largest_motion(model, state, previous, largest) -> float:
    """Largest distance any particle moved since ``previous`` (then updated to the state)."""
    largest.zero_()
    wp.launch(motion_kernel(model.scalar), dim=model.num_strands, device=model.device,
              inputs=[*_head(model), state.positions, previous, largest])
    return float(largest.numpy()[0])


def preroll(solver, state, control, seconds: float, frame_dt: float, substeps: int, *,
            settle_rate: float = 2.0, resolve: bool = True, tolerance: float | None = None,
            longest: float = 8.0) -> PrerollReport:
    """Settle ``state`` with the roots and colliders held where ``control`` puts them (the caller
    sets the first frame's pose with start = end): frames of ``frame_dt`` seconds in ``substeps``
    substeps, velocities multiplied by ``exp(-settle_rate frame_dt)`` after each frame, for
    ``seconds``, then on, up to ``longest`` x ``seconds``, until no particle moves more than
    ``tolerance`` (default :func:`settle_tolerance`) over a frame: a groom draping over a lumpy
    head keeps sliding for seconds, and a fixed preroll that stops while it slides leaves the
    shot to finish the slide (a pop). ``longest`` is 8 since resting contact follows Coulomb
    friction (``kernels/features/collide.py``): hair slides where it used to stick, and
    ``tests/test_clean_start.py``'s lumpy head now settles in 3.8 s (3.4 s before), near the old
    limit of 4. Velocities (and the corrections) are zeroed at the end.
    With ``resolve``, particles inside a collider are moved out first (:func:`resolve_start`).
    A groom split over devices (the composites of :mod:`dftl_warp.simulation.multi_device`, whose
    ``parts`` hold each device's solver, State and Control) settles as one: every part steps each
    frame, and the groom has settled when no particle of any part moves more than the tolerance."""
    parts = ([(s.model, st, c) for s, st, c in zip(solver.parts, state.parts, control.parts)]
             if hasattr(state, "parts") else [(solver.model, state, control)])
    if resolve:
        resolve_parts(parts)
    tol = settle_tolerance(*(m for m, _, _ in parts)) if tolerance is None else float(tolerance)
    frames = int(math.ceil(float(seconds) / float(frame_dt) - 1e-9)) if seconds > 0 else 0
    most = int(math.ceil(float(longest) * frames)) if frames else 0
    factor = math.exp(-float(settle_rate) * float(frame_dt))
    previous = [wp.clone(st.positions) for _, st, _ in parts]
    largest = [wp.zeros(1, dtype=wp.float32, device=m.device) for m, _, _ in parts]
    motion, done = 0.0, 0
    while done < most:
        solver.advance(state, control, frame_dt / substeps, substeps)
        for m, st, _ in parts:
            damp_velocities(m, st, factor)
        done += 1
        if done >= frames:
            motion = max(largest_motion(m, st, p, big) for (m, st, _), p, big in zip(parts, previous, largest))
            if motion <= tol:
                break
        else:
            for (_, st, _), p in zip(parts, previous):
                wp.copy(p, st.positions)
    if done:
        for m, st, c in parts:
            st.write("velocities", None, zero=True)
            if st.corrections is not None:
                st.write("corrections", None, zero=True)
        if resolve:
            resolve_parts(parts)
        if control.features is not None:
            control.features.resync()
    return PrerollReport(done, done * float(frame_dt), done > 0 and motion <= tol, motion, tol)
