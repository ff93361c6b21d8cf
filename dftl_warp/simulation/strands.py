"""One-call simulation for scripts and studies: :func:`simulate_strands`."""

from __future__ import annotations

import warnings
from typing import NamedTuple

import numpy as np
import warp as wp

from ..core.devices import device_argument
from ..core.layout import incoming_lengths, strand_offsets
from ..core.model import Model, check_strand_arrays
from ..options import check_api
from ..solvers import DEFAULT_GRAVITY, build_solver, carries_corrections
from ..solvers.base import check_gravity, check_step
from ..checks import check_lengths
from .monitor import EnergyGrowthWarning
from .settings import unused_solver_options


class Recording(NamedTuple):
    """Recorded frames, input point order, world space, float64."""

    #: (frames, num_points, 3), m
    positions: np.ndarray
    #: (frames, num_points, 3), m/s
    velocities: np.ndarray


def simulate_strands(
    points,
    counts,
    *,
    steps: int,
    dt: float,
    gravity=DEFAULT_GRAVITY,
    damping: float = 1.0,
    correction: str = "prior",
    precision: str = "float32",
    device: str = "cpu",
    record_every: int = 1,
    solver: str = "dftl",
    velocities=None,
    roots=None,
    layout: str | None = None,
) -> Recording:
    """Simulate strands for ``steps`` steps of ``dt`` seconds and record every ``record_every``-th.

    Args:
        points: (N, 3) concatenated strand vertices (m); vertex 0 of each strand is its root.
        counts: (S,) vertex count of each strand.
        gravity: (3,) acceleration, m/s^2.
        damping, correction, solver: see :class:`~dftl_warp.solvers.dftl.DFTLSolver`; a ``damping``
            or ``correction`` other than the default that ``solver`` does not take is a warning.
        velocities: optional (N, 3) initial velocities, m/s.
        roots: optional (steps + 1, S, 3) root positions (m): ``roots[k]`` is where the roots are
            after step ``k``; ``roots[0]`` replaces the input roots.

    Returns:
        :class:`Recording` with frame 0 the initial state and ``steps // record_every`` more.

    Warns:
        :class:`~dftl_warp.simulation.monitor.EnergyGrowthWarning` (once, naming the step and the
        strand) when a recorded frame holds a non-finite position or velocity, or a particle farther
        from its root than :data:`BLOWN_UP_LENGTHS` strand lengths: the setting blew up (e.g. a
        ``dt`` far beyond the solver's stable range). The check reads the recording, which is on
        the host anyway (:func:`blow_up_note`).

    Raises:
        ValueError naming the argument: ``dt`` not a finite number > 0, ``gravity`` not 3 finite
        numbers, ``steps`` not an integer >= 0, ``record_every`` not an integer >= 1, a
        ``damping``, ``correction``, ``precision`` or ``solver`` the options table refuses,
        ``points`` and ``counts`` as :meth:`~dftl_warp.core.model.Model.from_strands` refuses them,
        ``velocities`` / ``roots`` of another shape or not finite, or a ``device`` Warp does not
        have here ("device 'gpu' is not available here (cpu): ...").
    """
    for name, value, least in (("steps", steps, 0), ("record_every", record_every, 1)):
        if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)) or value < least:
            raise ValueError(f"{name} must be an integer >= {least}, got {value!r}")
    check_step(dt)
    gravity = check_gravity(gravity)
    damping = check_api("damping", damping)
    correction = check_api("correction", correction)
    precision = check_api("precision", precision)
    solver = check_api("solver", solver)
    # counts went through astype(int64) first: 5.5 vertices became 5 without a word
    points, counts = check_strand_arrays(points, counts)
    for line in unused_solver_options({"damping": damping, "correction": correction}, {solver},
                                      subject="this run does not use"):
        warnings.warn(line, UserWarning, stacklevel=2)   # damping=0.5 with solver="pbd" did nothing silently
    if velocities is not None:
        velocities = _checked_rows("velocities", velocities, (points.shape[0], 3), "one (3,) row per point, m/s")
    if roots is not None:
        roots = _checked_rows("roots", roots, (steps + 1, counts.shape[0], 3), "(steps + 1, S, 3), m")
        if precision == "float32":   # finite here, inf in the float32 model
            check_lengths(roots.reshape(-1, 3), "roots (flattened rows)", "", error=ValueError)
        starts = strand_offsets(counts)
        points = points.copy()
        points[starts] = roots[0]
    device = device_argument(device)   # before ScopedDevice, whose message was Warp's bare "Invalid device identifier"
    with wp.ScopedDevice(device):
        model = Model.from_strands(points, counts, device=device, precision=precision, layout=layout,
                                   corrections=carries_corrections(solver, correction))
        sim = build_solver(model, solver, damping=damping, correction=correction, gravity=gravity)
        state = sim.state()
        control = model.control()
        if velocities is not None:
            state.write("velocities", model.points_to_device(velocities, relative=False))

        def record():
            positions.append(model.points_from_device(state.positions))
            vels.append(model.points_from_device(state.velocities, relative=False))

        positions, vels = [], []
        record()
        for k in range(1, steps + 1):
            if roots is not None:
                control.set_root_targets(roots[k])
            sim.step(state, state, control, dt)
            if k % record_every == 0:
                record()
    recording = Recording(np.stack(positions), np.stack(vels))
    line = blow_up_note(recording, counts, record_every, f"simulate_strands: {solver}, dt={dt:g} s")
    if line is not None:
        warnings.warn(line, EnergyGrowthWarning, stacklevel=2)
    return recording


#: a particle farther from its strand's root than this many strand lengths has blown up (an
#: inextensible strand reaches one length; the pbd solver's stretch at its coarsest steps, about 15)
BLOWN_UP_LENGTHS = 100.0


def blow_up_note(recording: Recording, counts: np.ndarray, record_every: int, setting: str) -> str | None:
    """The warning for the first recorded frame in which the run blew up, naming its step and
    strand as the energy monitor does: a non-finite position or velocity, or a particle farther
    from its root than :data:`BLOWN_UP_LENGTHS` times its strand's length (pbd at an absurd step
    flies off to 1e13 m, finite). None when no frame did. Reads the host recording only."""
    counts = np.asarray(counts)
    offsets = strand_offsets(counts, with_end=True)
    strand_of = np.repeat(np.arange(counts.size), counts)
    lengths = np.bincount(strand_of, weights=incoming_lengths(recording.positions[0], counts), minlength=counts.size)
    finite = np.isfinite(recording.positions).all(axis=2) & np.isfinite(recording.velocities).all(axis=2)
    with np.errstate(invalid="ignore", over="ignore"):
        reach = np.linalg.norm(recording.positions - recording.positions[:, offsets[:-1]][:, strand_of], axis=2)
        far = reach > BLOWN_UP_LENGTHS * lengths[strand_of]
    bad = ~finite | (far & (lengths[strand_of] > 0.0))
    frames = np.flatnonzero(bad.any(axis=1))
    if not frames.size:
        return None
    f = int(frames[0])
    which = ~finite[f] if not finite[f].all() else bad[f]
    strands = np.unique(strand_of[np.flatnonzero(which)])
    more = f" (and {strands.size - 1} more)" if strands.size > 1 else ""
    what = ("non-finite positions or velocities" if not finite[f].all() else
            f"a particle {np.nanmax(reach[f][strand_of == strands[0]]) / lengths[strands[0]]:.3g} times its length "
            "from its root")
    return (f"{setting}: strand {int(strands[0])}{more}: {what} at step {f * record_every}; this setting is "
            "unstable (a smaller dt may hold it)")


def _checked_rows(name: str, values, shape: tuple, what: str) -> np.ndarray:
    """``values`` as a float64 array of ``shape``; ValueError naming ``name`` otherwise, or naming
    its first non-finite row."""
    try:
        a = np.asarray(values, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be numbers: {what}") from None
    if a.shape != shape:
        raise ValueError(f"{name} must have shape {shape}: {what}; got {a.shape}")
    bad = ~np.isfinite(a).all(axis=-1)
    if bad.any():
        index = ", ".join(str(int(i)) for i in np.unravel_index(int(np.argmax(bad)), bad.shape))
        raise ValueError(f"{name}[{index}] is not finite")
    return a
