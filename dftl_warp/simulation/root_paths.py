"""The C1 root path of a :class:`~dftl_warp.simulation.simulate.Simulation` (docs/elastic.md).

Across the frame ``f -> f + 1`` an animated prim's roots (and the elastic solver's clamp ghosts;
for roots bound to an animated mesh :func:`bound_clamps`) follow the Control's cubic Hermite
curve (:class:`~dftl_warp.core.state.Control`, :mod:`dftl_warp.kernels.core.root_path`) whose end
velocities are fourth-order differences of their positions over the 5 frames around (the window
moved inside the shot near its ends, one-sided at them: :func:`~dftl_warp.core.state.frame_velocity`;
the shot is the first frame and ``Simulation.last_frame``): the velocity a root is given no longer
jumps at every frame. The prim's local-to-world matrix follows the same curve (the roots are linear
in it), and :func:`matrix_rate` is its velocity over the frame's last substep, which turns the
written world velocities into local ones. Animated collider poses follow the same curve (their
rates from the same differences: :func:`~dftl_warp.features.colliders.update_from_scene`); a
deforming collider mesh moves linearly between frames (:func:`collider_note`).
"""

from __future__ import annotations

import math

import numpy as np


def shot(sim) -> tuple:
    """The shot's first and last frame (``inf`` while the last is unknown)."""
    return sim.first_frame, math.inf if sim.last_frame is None else sim.last_frame


def group_points(sim, what: str, k: int, group, frame: int):
    """Group ``k``'s world roots (``what="roots"``) or clamp ghosts (``"clamps"``) at ``frame``,
    computed once per frame (``sim._at_frame``, forgotten with old frames)."""
    key = (what, k, frame)
    points = sim._at_frame.get(key)
    if points is None:
        points = sim._at_frame[key] = (sim._roots_world(group, frame) if what == "roots"
                                       else group.clamps.world(sim._matrix, group.members, frame))
    return points


def frame_path(sim, what: str, k: int, group, frame: int, nxt: int) -> dict:
    """Targets and velocities of the C1 path of group ``k``'s roots or clamp ghosts over the frame
    ``frame -> nxt = frame + 1``: keyword arguments of ``Control.set_root_targets`` and
    ``ElasticSolver.set_clamp_targets`` (with the clamps' rotations at both ends). This frame's start is the last frame's end: the same array."""
    from ..core.state import frame_velocity

    duration = (nxt - frame) / sim.scene.stage.time_codes_per_second
    first, last = shot(sim)

    def points_at(f):
        return group_points(sim, what, k, group, f)

    path = {"start": points_at(frame), "end": points_at(nxt),
            "velocity_start": frame_velocity(points_at, frame, first, last, duration),
            "velocity_end": frame_velocity(points_at, nxt, first, last, duration), "frame_duration": duration}
    if what == "clamps":   # and the clamps' rotations (the root frames' twist about the first segment)
        path["rotation_start"] = group.clamps.rotations(sim._matrix, group.members, frame)
        path["rotation_end"] = group.clamps.rotations(sim._matrix, group.members, nxt)
    return path


def bound_clamps(group) -> None:
    """After ``update_frame`` bound an elastic group's roots to its animated ``dftl:rootMesh``: its
    clamp ghosts turn with the roots' triangles, on the same path
    (:meth:`~dftl_warp.solvers.elastic.ElasticSolver.bind_clamps`; the prims' transforms do not
    move them then)."""
    mesh = group.curves[0].root_mesh
    if group.clamps is not None and mesh is not None and mesh.animated:
        group.solver.bind_clamps(group.control)


def matrix_rate(sim, index: int, frame: int, substeps: int) -> np.ndarray:
    """How fast prim ``index``'s local-to-world matrix moved over the last of ``substeps``
    substeps of the frame ending at ``frame``, per second.

    The matrix follows the roots' path (the Hermite curve with the same difference tangents:
    linear in the matrix), and a root's written velocity is its last substep's backward
    difference, so this backward difference of the matrix's path is the velocity the simulation
    gave a point fixed in the prim: the roots' local velocity comes out zero (to the model
    precision's round-off). With ``u = 1 - 1/K``, ``H(1) - H(u) = (1 - u) chord - u (1 - u)
    ((1 - u) d0 - u d1)`` (:mod:`dftl_warp.kernels.core.root_path`); on a linear path (``d = 0``)
    it is ``chord / T``.
    """
    from ..core.state import frame_velocity

    duration = 1.0 / sim.scene.stage.time_codes_per_second
    first, last = shot(sim)

    def matrix_at(f):
        return sim._matrix(index, f)

    m0, m1 = matrix_at(frame - 1), matrix_at(frame)
    chord = m1 - m0
    d0 = duration * frame_velocity(matrix_at, frame - 1, first, last, duration) - chord
    d1 = duration * frame_velocity(matrix_at, frame, first, last, duration) - chord
    u = 1.0 - 1.0 / substeps
    return (chord / substeps - u * (1.0 - u) * ((1.0 - u) * d0 - u * d1)) * (substeps / duration)


def collider_note(scene) -> str | None:
    """The start note of a scene with deforming collider meshes (None without): animated
    collider *poses* follow the roots' C1 path inside each frame
    (:func:`~dftl_warp.features.colliders.update_from_scene`), but a deforming mesh moves linearly from
    one frame's points to the next's (interpolated every substep)."""
    deforming = [c.path for c in scene.colliders if c.points_sampler is not None]
    if not deforming:
        return None
    more = f" and {len(deforming) - 1} more" if len(deforming) > 1 else ""
    return (f"deforming collider {deforming[0]}{more}: its points move linearly from frame to frame (interpolated "
            "every substep); poses follow the roots' C1 path")


#: the largest turn (degrees) of an animated prim from one frame to the next that its once-a-frame
#: root path follows: the path's velocities are fourth-order differences of the frames' positions,
#: which on a circle sampled every theta give (8 sin theta - sin 2 theta) / (6 theta) of the speed:
#: 0.97 at 60 degrees, 0.85 at 90, 0.31 at 150, and beyond 180 the turn goes the other way
MAX_TURN_DEGREES = 90.0


def turn_degrees(m0: np.ndarray, m1: np.ndarray) -> float:
    """The angle (degrees) of the rotation between the 4x4 matrices' linear parts (their polar
    rotations: scale and shear left out)."""
    def rotation(m):
        u, _, vt = np.linalg.svd(np.asarray(m, dtype=np.float64)[:3, :3])
        return u @ vt

    cos = 0.5 * (float(np.trace(rotation(m0).T @ rotation(m1))) - 1.0)
    return math.degrees(math.acos(min(1.0, max(-1.0, cos))))


def warn_fast_turns(sim, group, frame: int, nxt: int) -> None:
    """One warning per animated prim of ``group`` that turns more than :data:`MAX_TURN_DEGREES`
    from ``frame`` to ``nxt``: its roots' path then runs slower than the prim turns (about 3x at
    150 degrees a frame, 10 turns a second at 24 fps)."""
    for i in group.members:
        c = sim.scene.curves[i]
        if not c.animated or c.path in sim.fast_turns:
            continue
        degrees = turn_degrees(sim._matrix(i, frame), sim._matrix(i, nxt))
        if degrees > MAX_TURN_DEGREES:
            sim.fast_turns.add(c.path)
            sim.warn(f"{sim.scene.source}: {c.path}: turns {degrees:.0f} degrees from frame {frame} to {nxt} (more "
                     f"than {MAX_TURN_DEGREES:.0f}): its roots, sampled once a frame, follow the turn slower than "
                     f"it is (a third of its speed at 150 degrees a frame); author the motion at more frames a second")
