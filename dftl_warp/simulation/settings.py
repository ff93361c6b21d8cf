"""The settings of a simulation run and of each group of prims simulated together.

:class:`SimulationOptions` are a run's settings (command line or API); :func:`group_settings`
resolves each prim's solver settings (command line, else the prim's ``dftl:`` attributes, else the
defaults; a prim that sets no solver gets :func:`automatic_solver`'s); :func:`resolve_frames` the
frame range.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields

import numpy as np

from ..core.bounds import box
from ..errors import UserError
from ..options import MAX_FRAME, MAX_FRAMES, check_api, default
from ..solvers.base import SOLVER_OPTION_TEXT, unused_solver_options  # noqa: F401  (simulate's, strands')
from ..usd.scene import Scene

#: values used where neither the command line nor a prim's ``dftl:`` attribute says otherwise (the
#: options table's defaults, :mod:`dftl_warp.options`; these names are kept for scripts)
#: the solver of prims without widths (a prim with widths gets the elastic solver: automatic_solver)
DEFAULT_SOLVER = "dftl"
DEFAULT_DAMPING = default("damping")
DEFAULT_CORRECTION = default("correction")
DEFAULT_SUBSTEPS = default("substeps")


@dataclass
class SimulationOptions:
    """Settings of a run. ``None`` defers to the prims' ``dftl:`` attributes, then the defaults
    (the options table, :mod:`dftl_warp.options`).

    Command-line values override ``dftl:`` attributes. Every value is checked against the table
    when the options are made: a bad one raises :class:`~dftl_warp.options.OptionError` (a
    ValueError and a UserError) naming the field.
    """

    start: int | None = None
    end: int | None = None
    substeps: int | None = None
    damping: float | None = None
    correction: str | None = None
    solver: str | None = None
    precision: str = field(default=default("precision"))
    #: the elastic solver's arithmetic (its ``compute_precision``); other solvers compute in ``precision``
    arithmetic: str = field(default=default("arithmetic"))
    device: str = field(default=default("device"))
    prims: list[str] | None = None
    #: Gauss-Seidel iterations per step of the pbd solver
    iterations: int | None = None
    #: watch each group's energy and warn once when it grows without bound (dftl_warp.simulation.monitor)
    monitor: bool = field(default=default("monitor"))
    #: seconds of settling at the first frame's pose before the shot (dftl_warp.features.clean_start)
    preroll: float = field(default=default("preroll"))
    #: a quality preset (dftl_warp.simulation.quality): its solver for the prims that would run the plain
    #: chain; prims that run the elastic solver by default keep it (the preset's substeps and precision
    #: come through ``substeps`` and ``precision``, as the command line fills them)
    quality: str | None = None

    def __post_init__(self):
        for f in fields(self):
            value = getattr(self, f.name)
            if value is None:  # None: unset (a field with a default of its own takes it)
                setattr(self, f.name, f.default)
                continue
            setattr(self, f.name, check_api(f.name, value))


@dataclass(frozen=True)
class GroupSettings:
    """The solver settings shared by every prim of one simulation group."""

    solver: str
    damping: float
    correction: str
    substeps: int
    #: elastic solver: the authored shape is the equilibrium under gravity (``dftl:inverseStatics``)
    inverse_statics: bool = True


def resolve_frames(scene: Scene, start=None, end=None) -> tuple[int, int]:
    """First and last integer frame: the flags, else the stage's start/end time codes."""
    info = scene.stage
    if start is None and info.start_time_code is None:
        raise UserError(f"{scene.source}: the stage has no startTimeCode/endTimeCode; give --start and --end")
    if end is None and info.end_time_code is None:
        raise UserError(f"{scene.source}: the stage has no endTimeCode; give --end")
    used = [code for code, flag in ((info.start_time_code, start), (info.end_time_code, end)) if flag is None]
    if any(abs(code) > MAX_FRAME for code in used):   # where a double cannot tell frames apart (options.MAX_FRAME)
        codes = f"{info.start_time_code:.17g}..{info.end_time_code:.17g}"
        raise UserError(f"{scene.source}: the stage's time range {codes} (startTimeCode..endTimeCode) reaches past "
                        f"+-{float(MAX_FRAME):g}, where a time code (a double) cannot tell frames apart; give --start "
                        f"and --end")
    first = int(start) if start is not None else math.ceil(info.start_time_code - 1e-9)
    last = int(end) if end is not None else math.floor(info.end_time_code + 1e-9)
    if last < first:
        raise UserError(f"{scene.source}: frame range {first}..{last} is empty (end before start)")
    if last - first + 1 > MAX_FRAMES:   # a typo that would run for days
        raise UserError(f"{scene.source}: frames {first}..{last} are {last - first + 1} frames; a run takes at most "
                        f"{MAX_FRAMES} (check --start and --end)")
    return first, last


def frame_range_note(scene, first: int, last: int) -> None:
    """Add a warning to ``scene.warnings`` when frames ``first..last`` reach outside the stage's
    ``startTimeCode``..``endTimeCode`` and something in it is animated (a transform, a mesh's
    points, a time-sampled wind): there the animation holds its first or last pose. A stage
    without a time range or without animation gets none."""
    start, end = scene.stage.start_time_code, scene.stage.end_time_code
    if start is None or end is None or (start <= first and last <= end):
        return
    prims = [*scene.curves, *(c.root_mesh for c in scene.curves if c.root_mesh is not None), *scene.colliders]
    wind = scene.features.get("wind")
    if not any(getattr(p, "animated", False) or getattr(p, "points_sampler", None) is not None for p in prims) \
            and not (wind is not None and getattr(wind, "ndim", 0) == 2):
        return
    where = "outside" if last < start or first > end else "partly outside"
    scene.warnings.append(f"{scene.source}: frames {first}..{last} lie {where} the stage's time range "
                          f"{start:g}..{end:g} (startTimeCode..endTimeCode): there the animation holds its "
                          f"first or last pose")


def last_written_frame(scene, first: int, last: int, step: int, flag: str = "--frame-step") -> int:
    """The last frame ``first + k * step`` within ``first..last`` (what a run with that frame step
    writes and simulates up to). Frames after it are left out: one warning in ``scene.warnings``
    names them (``flag``: how the option is spelt, ``--frame-step`` or ``frame_step``)."""
    step = max(1, int(step))
    written = first + (last - first) // step * step
    if written < last:
        left = f"frame {last} is" if last == written + 1 else f"frames {written + 1}..{last} are"
        scene.warnings.append(f"{flag} {step}: frames {first}..{last} end between written frames: the output "
                              f"ends at frame {written}, and {left} neither simulated nor written")
    return written


def automatic_solver(scene: Scene, options: SimulationOptions, index: int) -> str:
    """The solver of ``scene.curves[index]`` where neither the command line nor the prim sets one:
    ``elastic`` for a prim with widths (hair of that thickness bends: docs/elastic.md) unless it
    authors ``dftl:bending = false``, else ``dftl`` (under ``--tolerance`` too, which drives the
    elastic solver: docs/tolerance.md)."""
    c = scene.curves[index]
    if c.settings.bending is False or c.widths is None:
        return DEFAULT_SOLVER
    if not np.any(np.asarray(c.widths) > 0):
        # widths authored, every one zero: no thickness to bend with (said, not silently)
        line = (f"{scene.source}: {c.path}: every width is 0: it runs as a plain DFTL chain, without hair's "
                f"bending stiffness (author its widths, or dftl:bending = false to say this is meant)")
        if line not in scene.warnings:
            scene.warnings.append(line)
        return DEFAULT_SOLVER
    return "elastic"


def group_settings(scene: Scene, options: SimulationOptions, index: int) -> GroupSettings:
    """Settings of ``scene.curves[index]``: command line, else ``dftl:`` attributes, else defaults
    (the solver: :func:`automatic_solver`)."""
    s = scene.curves[index].settings

    def pick(flag, attr, default):
        return flag if flag is not None else attr if attr is not None else default

    solver = pick(options.solver, s.solver, None)
    if solver is None:
        solver = automatic_solver(scene, options, index)
        if solver == DEFAULT_SOLVER and options.quality is not None:
            from .quality import quality_preset

            solver = quality_preset(options.quality)["solver"]
    return GroupSettings(
        solver=solver,
        # every solver's damping defaults to the table's 1 (the elastic solver's too: with s < 1 it does
        # not converge to the constrained dynamics, docs/elastic/convergence.md)
        damping=float(pick(options.damping, s.damping, DEFAULT_DAMPING)),
        correction=pick(options.correction, s.correction, DEFAULT_CORRECTION),
        substeps=int(pick(options.substeps, s.substeps, DEFAULT_SUBSTEPS)),
        inverse_statics=bool(pick(None, s.inverse_statics, default("inverse_statics"))),
    )


def unused_prim_settings(scene: Scene, index: int, settings: GroupSettings, options) -> list[str]:
    """One warning per ``dftl:damping`` / ``dftl:correction`` authored on ``scene.curves[index]``
    (and not overridden by ``options``) that the prim's solver does not take: ``dftl:solver = "pbd"``
    with ``dftl:damping = 0.5`` ignored the damping without a word. Defaults stay quiet."""
    from ..solvers import SOLVERS

    c = scene.curves[index]
    out = []
    for name in ("damping", "correction"):
        value = getattr(c.settings, name)
        if value is None or getattr(options, name) is not None or value == default(name):
            continue
        if name not in SOLVERS[settings.solver].options:
            out.append(f"{scene.source}: {c.path}: dftl:{name} = {value!r} does nothing: its solver, "
                       f"{settings.solver}, has no {SOLVER_OPTION_TEXT[name]}")
    return out


def describe_setting(scene: Scene, members: list[int], settings: GroupSettings, options) -> str:
    """How a group is simulated, as the energy monitor's warning names it."""
    prims = f"{scene.source}: " + ", ".join(scene.curves[i].path for i in members)
    dt = 1.0 / (scene.stage.time_codes_per_second * settings.substeps)
    return (f"{prims}: {settings.solver} damping={settings.damping:g} {settings.correction}, "
            f"{settings.substeps} substeps/frame (dt={dt:.3g} s), {options.precision}")


#: largest world extent (stage units) a precision simulates without overflowing squared lengths
MAX_EXTENT = {"float32": 1.0e15, "float64": 1.0e150}


def check_extent(points, offsets, curves, source, precision) -> None:
    """Refuse scenes too large for the precision (squared lengths would overflow)."""
    if points.shape[0] == 0:
        return
    lo, hi = box(points)
    centre = 0.5 * (lo + hi)
    distance = np.abs(points - centre).max(axis=1)
    limit = 0.5 * MAX_EXTENT[precision]
    if distance.max() > limit:
        i = int(np.argmax(distance))
        k = int(np.searchsorted(offsets, i, side="right") - 1)
        raise UserError(
            f"{source}: {curves[k].path}: points[{i - offsets[k]}] is {distance[i]:.3g} units from the centre "
            f"of the hair: too far apart to simulate in {precision}"
        )
