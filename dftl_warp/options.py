"""The one table of options: every setting of a simulation run and every ``dftl:`` USD attribute.

Each :class:`Option` holds its name, type, default, range or choices, unit and help, and how each
front end spells it: the ``dftl-warp simulate`` flag (``cli``), the USD attribute (``usd``, read on
the prims named by ``scope``), the batch TOML key (``toml``) and the Python keyword of
:class:`~dftl_warp.simulation.settings.SimulationOptions` / ``simulate_usd(**options)``
(``api``). The front ends validate through :meth:`Option.check` and format its
:class:`BadValue` in their own words:

- the command line builds its arguments with :func:`add_arguments`;
- the USD reader (:mod:`dftl_warp.usd.attributes`) checks the authored ``dftl:`` attributes and
  warns about unknown ones (:func:`unknown_message`);
- the batch TOML (:mod:`dftl_warp.batch.jobs`) checks each key;
- the Python API checks its keywords (:func:`check_api`, :class:`OptionError`).

A foundation module: it imports only :mod:`dftl_warp.errors`, the standard library and numpy.
Names that live in higher layers (the solver registry, the quality presets, the precisions, the
feature attributes) are written out here; ``tests/test_options.py`` checks that they agree.
"""

from __future__ import annotations

import difflib
import math
import re
from dataclasses import dataclass, replace

import numpy as np

from .errors import UserError

#: the ``dftl:`` namespace of the USD attributes
NAMESPACE = "dftl:"

#: ``device`` values: cpu, cuda, cuda:N, or a comma-separated list of those (split across devices)
DEVICE_PATTERN = re.compile(r"^(cpu|cuda(:\d+)?)(,(cpu|cuda(:\d+)?))*$")

#: where a USD attribute is read: BasisCurves prims, the scene prim (the UsdPhysics.Scene prim,
#: else the default prim), both, or prims with UsdPhysics.CollisionAPI
SCOPES = ("curves", "scene", "both", "collider")


class OptionError(UserError, ValueError):
    """A bad option value given to the Python API: a :class:`ValueError` for scripts and a
    :class:`~dftl_warp.errors.UserError` (one line, exit status 2) for the command line."""


class BadValue(ValueError):
    """``value`` is not valid for ``option``. ``kind`` is "type", "range" or "choice";
    ``expected`` completes "must be ..." (``an integer``, ``in [0, 1]``, ``one of a, b``)."""

    def __init__(self, option: Option, value, kind: str, expected: str):
        self.option, self.value, self.kind, self.expected = option, value, kind, expected
        super().__init__(f"{option.name} must be {expected}, got {value!r}")


@dataclass(frozen=True)
class Option:
    """One option: what it is, and how each front end spells it (None: not offered there)."""

    #: the option's name (the Python keyword where ``api`` is set)
    name: str
    #: int, float, str, bool, "paths" (prim paths), "float3" (3 numbers) or "rel" (a relationship)
    type: object
    #: the value used when nobody sets it (None: decided elsewhere, as ``help`` says)
    default: object
    help: str
    #: physical unit of the value ("" when none)
    unit: str = ""
    #: the allowed values of a str option, in the order help lists them
    choices: tuple = ()
    #: numeric range: ``low`` <= value (< when ``low_open``), value <= ``high``
    low: float | None = None
    low_open: bool = False
    high: float | None = None
    #: the largest sane value of an unbounded range: more is refused as a typo ("must be at most")
    #: that would run for days (``--substeps 1000000000``); help lists it after the range
    limit: float | None = None
    #: regular expression a str option must match (after removing spaces)
    pattern: re.Pattern | None = None
    #: ``dftl-warp simulate`` flag, its metavar, and whether it may repeat (a list)
    cli: str | None = None
    metavar: str | None = None
    repeat: bool = False
    #: USD attribute and the prims it is read on (:data:`SCOPES`)
    usd: str | None = None
    scope: str = ""
    #: batch TOML key
    toml: str | None = None
    #: Python keyword (SimulationOptions field, simulate_usd keyword)
    api: str | None = None
    #: a retired USD attribute: why, and what replaces it (the reader refuses it with this text)
    retired: str = ""

    # -- checking ------------------------------------------------------------------------------

    @property
    def range_text(self) -> str:
        """``in [0, 1]``, ``>= 1``, ``> 0`` or "" (no range)."""
        if self.low is not None and self.high is not None:
            return f"in {'(' if self.low_open else '['}{_num(self.low)}, {_num(self.high)}]"
        if self.low is not None:
            return f"{'>' if self.low_open else '>='} {_num(self.low)}"
        if self.high is not None:
            return f"<= {_num(self.high)}"
        return ""

    def _type_text(self) -> str:
        if self.type is int:
            return "an integer"
        if self.type is float:
            return "a number" + (f" {self.range_text}" if self.range_text else "")
        if self.type is bool:
            return "true or false"
        if self.type == "paths":
            return "a prim path or a list of prim paths (starting with /)"
        if self.type == "float3":
            return "3 finite numbers"
        if self.type == "rel":
            return "a relationship"
        if self.pattern is not None:
            if self.name == "guides":
                return "a number of guides, a fraction or a percentage (such as 10, 0.1 or 10%)"
            return "cpu, cuda:N or a comma-separated list of them" if self.name == "device" else "a string"
        if self.choices:
            return self._choice_text()
        return "a string"

    def _choice_text(self) -> str:
        return "one of " + ", ".join(self.choices)

    def check(self, value):
        """``value`` checked and normalised (int for int, float for float, a list for paths);
        raises :class:`BadValue`. None is not a value: callers skip unset options."""
        kind = self.type
        if kind is bool:
            if not isinstance(value, (bool, np.bool_)):
                raise BadValue(self, value, "type", self._type_text())
            return bool(value)
        if kind is int:
            ok = isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, (bool, np.bool_))
            # an int is whole however large (float(10**20) != 10**20 called it "not an integer")
            whole = isinstance(value, (int, np.integer)) or (ok and math.isfinite(value) and float(value) == int(value))
            if not ok or not whole:
                raise BadValue(self, value, "type", self._type_text())
            value = int(value)
            self._check_range(value)
            return value
        if kind is float:
            if not isinstance(value, (int, float, np.integer, np.floating)) or isinstance(value, (bool, np.bool_)):
                raise BadValue(self, value, "type", self._type_text())
            value = float(value)
            if not math.isfinite(value):
                if value > 0 and self.limit is not None and self.high is None:   # inf breaks the limit, not >= low
                    raise BadValue(self, value, "range", f"at most {_num(self.limit)}")
                if self.range_text:
                    raise BadValue(self, value, "range", self.range_text)
                raise BadValue(self, value, "type", "a finite number")
            self._check_range(value)
            return value
        if kind is str:
            if self.choices:
                if not isinstance(value, str) or value not in self.choices:
                    raise BadValue(self, value, "choice", self._choice_text())
                return value
            if not isinstance(value, str):
                raise BadValue(self, value, "type", self._type_text())
            if self.pattern is not None:
                value = value.replace(" ", "")
                if not self.pattern.match(value):
                    raise BadValue(self, value, "type", self._type_text())
            return value
        if kind == "paths":
            items = [value] if isinstance(value, str) else value
            if not isinstance(items, (list, tuple)) or not items \
                    or not all(isinstance(p, str) and p.startswith("/") for p in items):
                raise BadValue(self, value, "type", self._type_text())
            return list(items)
        if kind == "float3":
            try:
                v = np.array(value, dtype=np.float64).reshape(3)
            except (TypeError, ValueError):
                raise BadValue(self, value, "type", self._type_text()) from None
            if not np.isfinite(v).all():
                raise BadValue(self, value, "type", self._type_text())
            return v
        return value

    def _check_range(self, value) -> None:
        if self.low is not None and (value <= self.low if self.low_open else value < self.low):
            raise BadValue(self, value, "range", self.range_text)
        if self.high is not None and value > self.high:
            raise BadValue(self, value, "range", self.range_text)
        if self.limit is not None and value > self.limit:
            raise BadValue(self, value, "range", f"at most {_num(self.limit)}")


def _num(x) -> str:
    return f"{x:g}"


# -- the table ------------------------------------------------------------------------------------

#: the solver registry's names (dftl_warp.solvers.SOLVERS; the table is below the registry)
SOLVER_NAMES = ("dftl", "ftl", "pbd", "reference", "elastic", "rattle")
#: the velocity correction forms (dftl_warp.kernels.solvers.ftl.CORRECTIONS)
CORRECTION_NAMES = ("prior", "posterior")
#: the floating-point precisions (dftl_warp.core.precision.PRECISIONS)
PRECISION_NAMES = ("float32", "float64")
#: the quality presets (dftl_warp.simulation.quality.QUALITY_PRESETS)
QUALITY_NAMES = ("draft", "production", "reference")

#: why ``dftl:shapeStiffness`` is refused, and what replaces it
SHAPE_STIFFNESS_RETIRED = (
    "shape retention is retired (it pulled positions toward the rest shape every substep, which "
    "buzzed at frame rate and wrote velocities 4-16x the motion): strands with widths keep their "
    "style as elastic rods of hair by default (docs/elastic.md); scale their stiffness with "
    "primvars:dftl:bendStiffnessScale, give a rest shape with physics:restShapePoints, and remove "
    "dftl:shapeStiffness")

#: the most substeps per frame: 16x the most --tolerance picks (1024), twice the finest
#: reference of scripts/ (8192); a value past it is a typo that would run for days
MAX_SUBSTEPS = 16384
#: the most pbd iterations per step (4 by default): a value past it is a typo
MAX_ITERATIONS = 1024
#: the longest preroll, in seconds: a groom settles in seconds (docs/features.md: 3.8 s on a
#: lumpy head), and the preroll may go on up to 8x as long
MAX_PREROLL = 60.0
#: the largest frame number (either sign): past 2**53 (9.007e15) consecutive frames are one USD
#: time code (a double), so 4 frames were written as 3 samples at the wrong times
MAX_FRAME = 10 ** 15
#: the most frames in one run (11.6 hours at 24 fps): a longer range is a typo that would run for
#: days or weeks (``--end 1000000000`` on a 10-frame stage: weeks, even for 3 strands on the CPU)
MAX_FRAMES = 1_000_000

_RUN = [
    Option("start", int, None, "first frame (default: the stage's startTimeCode)", low=-MAX_FRAME, high=MAX_FRAME,
           cli="--start", metavar="F", toml="start", api="start"),
    Option("end", int, None, f"last frame, inclusive (default: the stage's endTimeCode; at most {MAX_FRAMES} "
           "frames in a run)", low=-MAX_FRAME, high=MAX_FRAME, cli="--end", metavar="F", toml="end", api="end"),
    Option("substeps", int, 8, "solver steps per frame", low=1, limit=MAX_SUBSTEPS,
           cli="--substeps", metavar="N", usd="dftl:substeps", scope="curves", toml="substeps", api="substeps"),
    Option("damping", float, 1.0,
           "share of the follow-the-leader correction removed from velocities", low=0.0, high=1.0,
           cli="--damping", metavar="S", usd="dftl:damping", scope="curves", toml="damping", api="damping"),
    Option("correction", str, "prior", "velocity correction form", choices=CORRECTION_NAMES,
           cli="--correction", usd="dftl:correction", scope="curves", toml="correction", api="correction"),
    Option("solver", str, None, "solver (unset: elastic for prims with widths, which bend like hair of "
           "their thickness, docs/elastic.md; dftl for prims without)", choices=SOLVER_NAMES,
           cli="--solver", usd="dftl:solver", scope="curves", toml="solver", api="solver"),
    Option("bending", bool, True,
           "false: a prim with widths stays the plain DFTL chain where no solver is set (no bending "
           "stiffness)", usd="dftl:bending", scope="curves"),
    Option("inverse_statics", bool, True,
           "elastic solver: the authored shape is the equilibrium under gravity (false: it sags "
           "toward its rest shape)", usd="dftl:inverseStatics", scope="curves"),
    Option("iterations", int, 4, "Gauss-Seidel iterations per step of --solver pbd", low=1, limit=MAX_ITERATIONS,
           cli="--iterations", metavar="K", toml="iterations", api="iterations"),
    Option("precision", str, "float32", "floating-point precision", choices=PRECISION_NAMES,
           cli="--precision", toml="precision", api="precision"),
    Option("arithmetic", str, "float64",
           "elastic solver: the precision it computes in (the State keeps --precision); float32 runs about "
           "2x faster on the GPU, and a styled strand at rest then holds its shape to float32 round-off "
           "(docs/elastic.md)", choices=PRECISION_NAMES, cli="--arithmetic", toml="arithmetic", api="arithmetic"),
    Option("quality", str, None,
           "a measured preset of solver, substeps and precision (docs/accuracy.md); explicit flags "
           "override its parts", choices=QUALITY_NAMES, cli="--quality", toml="quality", api="quality"),
    Option("device", str, None,
           "cpu or cuda:N; a list (cuda:0,cuda:1) splits the strands across devices; unset: cuda:0 "
           "when Warp finds a CUDA device, else cpu ($DFTL_WARP_DEVICE overrides)",
           pattern=DEVICE_PATTERN, cli="--device", toml="device", api="device"),
    Option("prims", "paths", None, "simulate only the BasisCurves prims at or below PATH (repeatable)",
           cli="--prim", metavar="PATH", repeat=True, toml="prim", api="prims"),
    Option("monitor", bool, True,
           "watch each group's energy and warn once when it grows without bound", api="monitor"),
]

_USD = [
    Option("simulate", bool, True, "false leaves the prim out of the simulation",
           usd="dftl:simulate", scope="curves"),
    Option("friction", float, None,
           "Coulomb friction coefficient (overrides the bound physics material's dynamicFriction)",
           low=0.0, usd="dftl:friction", scope="collider"),
    Option("collisionSdf", bool, None,
           "mesh colliders: true collides through a signed distance field rebuilt when the points change "
           "(exact mesh queries where it cannot answer), false through exact mesh queries; unset: the field "
           "from 20000 triangles on (docs/features.md)", usd="dftl:collisionSdf", scope="collider"),
    Option("collisionSdfCellSize", float, None,
           "cell of a mesh collider's signed distance field (default: the mesh's mean edge length)",
           unit="stage units", low=0.0, low_open=True, usd="dftl:collisionSdfCellSize", scope="collider"),
    # the feature attributes (dftl_warp.features.ATTRIBUTES; docs/features.md)
    Option("drag", float, 0.0, "air drag rate: velocities relax toward the air's velocity; 0: no drag",
           unit="1/s", low=0.0, usd="dftl:drag", scope="both"),
    Option("wind", "float3", None, "wind velocity, time-sampled for gusts; needs dftl:drag > 0",
           unit="stage units/s", usd="dftl:wind", scope="scene"),
    Option("windNoise", float, 0.0, "curl-noise amplitude added to the wind", unit="stage units/s",
           low=0.0, usd="dftl:windNoise", scope="scene"),
    Option("windNoiseScale", float, 0.1, "feature size of the noise", unit="stage units", low=0.0,
           low_open=True, usd="dftl:windNoiseScale", scope="scene"),
    Option("windNoiseFrequency", float, 1.0, "how fast the noise changes", unit="1/s",
           usd="dftl:windNoiseFrequency", scope="scene"),
    Option("windSeed", int, 0, "noise field selector", usd="dftl:windSeed", scope="scene"),
    Option("hairHair", bool, False, "true turns hair-hair interaction on", usd="dftl:hairHair", scope="scene"),
    Option("hairHairCellSize", float, None, "grid cell size (default 4 x the mean segment length)",
           unit="stage units", low=0.0, low_open=True, usd="dftl:hairHairCellSize", scope="scene"),
    Option("hairHairFriction", float, 2.0, "rate of relaxation toward the local mean velocity", unit="1/s",
           low=0.0, usd="dftl:hairHairFriction", scope="scene"),
    Option("hairHairRepulsion", float, None, "acceleration per unit difference of the hair's density relative "
           "to its rest density, across a cell (default 5 m/s^2: a groom's edge at rest is pushed out at about g/2)",
           unit="stage units/s^2", low=0.0, usd="dftl:hairHairRepulsion", scope="scene"),
    Option("hairHairThreshold", float, None, "relative density below which the hair exerts no repulsion "
           "(default the densest node at rest, which info prints: a groom at rest is not pushed; 0: all of it)",
           low=0.0, usd="dftl:hairHairThreshold", scope="scene"),
    Option("hairHairSplatInterval", int, 1,
           "substeps between rebuilds of the hair-hair grid (1: every substep; the substeps per frame or "
           "more: once per frame)", unit="substeps", low=1, usd="dftl:hairHairSplatInterval", scope="scene"),
    Option("shapeStiffness", float, None, "retired (shape retention)", usd="dftl:shapeStiffness", scope="both",
           retired=SHAPE_STIFFNESS_RETIRED),
    Option("collisionIterations", int, 2, "collide-and-restore rounds per particle", low=1,
           usd="dftl:collisionIterations", scope="scene"),
    Option("rootMesh", "rel", None,
           "a Mesh prim the roots are bound to (closest point at rest); follows its animated points",
           usd="dftl:rootMesh", scope="curves"),
]

#: every option by name
OPTIONS: dict[str, Option] = {o.name: o for o in _RUN + _USD}
#: options by USD attribute name (``dftl:damping`` -> Option)
BY_USD: dict[str, Option] = {o.usd: o for o in OPTIONS.values() if o.usd}
#: options by batch TOML key
BY_TOML: dict[str, Option] = {o.toml: o for o in OPTIONS.values() if o.toml}
#: options by Python keyword
BY_API: dict[str, Option] = {o.api: o for o in OPTIONS.values() if o.api}
#: the USD attributes that turn features on (those dftl_warp.features reads: features.ATTRIBUTES)
FEATURE_ATTRIBUTES = tuple(o.usd for o in _USD if o.usd not in ("dftl:simulate", "dftl:friction") and not o.retired)


def add_choice(name: str, value: str) -> None:
    """Accept ``value`` for the str option ``name`` everywhere (the solver registry calls this for a
    solver registered beyond :data:`SOLVER_NAMES`)."""
    option = OPTIONS[name]
    if value not in option.choices:
        object.__setattr__(option, "choices", option.choices + (value,))


def default(name: str):
    """The table's default of option ``name``."""
    return OPTIONS[name].default


def usd_attributes(scope: str) -> list[Option]:
    """The options read as USD attributes on prims of ``scope`` ("curves", "scene", "collider");
    those of scope "both" count for curves and scene."""
    return [o for o in OPTIONS.values() if o.usd and (o.scope == scope or (o.scope == "both" and scope in ("curves", "scene")))]


# -- front ends ----------------------------------------------------------------------------------


def check_keywords(options: dict, accepts, where: str) -> None:
    """A TypeError naming the first of ``options`` the dataclass ``accepts`` has no field for, with
    a did-you-mean among its fields and the options table's names (those the caller took already)."""
    import dataclasses

    fields = {f.name for f in dataclasses.fields(accepts)}
    for name in options:
        if name not in fields:
            raise TypeError(f"{where}: unknown keyword {name!r}{did_you_mean(name, sorted(fields | set(OPTIONS)))}")


def did_you_mean(name: str, known) -> str:
    """`` (did you mean 'x'?)`` for the closest of ``known``, or ""."""
    close = difflib.get_close_matches(name, list(known), n=1)
    return f" (did you mean {close[0]!r}?)" if close else ""


def unknown_message(names, known, suggest=None) -> str:
    """``unknown attribute dftl:dampng (did you mean dftl:damping?)`` for one or more names; each
    name's suggestion is among ``suggest(name)`` if given, else among ``known``."""
    parts = []
    for name in names:
        close = difflib.get_close_matches(name, sorted(suggest(name) if suggest else known), n=1)
        parts.append(name + (f" (did you mean {close[0]}?)" if close else ""))
    return f"unknown attribute{'s' if len(parts) > 1 else ''} " + ", ".join(parts)


def check_api(name: str, value):
    """``value`` of the Python keyword ``name`` checked (None passes: unset); raises
    :class:`OptionError` naming the keyword."""
    if value is None:
        return None
    option = BY_API[name]
    try:
        return option.check(value)
    except BadValue as exc:
        raise OptionError(f"{name} must be {exc.expected}, got {value!r}") from None


def check_toml(key: str, value):
    """``value`` of the batch TOML key ``key`` checked; ValueError in the TOML's words."""
    option = BY_TOML[key]
    try:
        return option.check(value)
    except BadValue as exc:
        raise ValueError(f"{key} must be {exc.expected}, got {value!r}") from None


def shown_value(value, attr=None) -> str:
    """``value`` as a message shows it: a float authored as a 32-bit ``float`` (or ``half``, per
    the USD attribute ``attr``) with the shortest digits that give it back (``-0.3``, not
    ``-0.30000001192092896``), others as ``repr``."""
    if isinstance(value, float):
        type_name = str(attr.GetTypeName()) if attr is not None else ""
        return str(np.float32(value)) if type_name in ("float", "half") else repr(value)
    if isinstance(value, (np.floating, np.integer)):
        return str(value)
    return repr(value)


#: the value types as the messages name them, with their article
_TYPE_TEXT = {int: "an integer", float: "a float", bool: "a bool", str: "a string"}


def usd_message(exc: BadValue, where: str, attribute: str | None = None, attr=None) -> str:
    """``FILE: PRIM: dftl:x = VALUE: problem`` for a bad authored attribute value (``attr``: the
    USD attribute, for how its value is shown)."""
    name = attribute or exc.option.usd
    head = f"{where}: {name} = {shown_value(exc.value, attr)}"
    if exc.kind == "type":
        if exc.expected == "a finite number":
            return f"{head}: expected a finite number"
        return f"{head}: expected {_TYPE_TEXT.get(exc.option.type, exc.expected)}"
    if exc.kind == "choice":
        choices = exc.option.choices
        if len(choices) == 2:
            return f"{head}: choose {choices[0]} or {choices[1]}"
        return f"{head}: choose one of {', '.join(choices)}"
    return f"{head}: must be {exc.expected}"


def _cli_type(option: Option):
    """An argparse ``type`` for ``option``: parse the text, then check it against the table."""
    import argparse

    def parse(text):
        try:
            value = option.type(text)
        except ValueError:
            raise argparse.ArgumentTypeError(
                f"not {'an integer' if option.type is int else 'a number'}: {text!r}") from None
        try:
            return option.check(value)
        except BadValue as exc:
            raise argparse.ArgumentTypeError(f"must be {exc.expected}, got {text}") from None

    parse.__name__ = option.type.__name__
    return parse


def cli_help(option: Option, default_text: str | None = None) -> str:
    """The flag's help: the table's help, unit and default."""
    text = option.help
    if option.range_text:
        text += f", {option.range_text}"
    if option.limit is not None:
        text += f", at most {_num(option.limit)}"
    if option.unit:
        text += f" ({option.unit})"
    if default_text is None and option.default is not None and option.cli != "--device":
        default_text = f"{option.default}"
    if default_text:
        text += f" (default {default_text})"
    return text


def add_arguments(parser, names, *, choices=None, defaults_from_usd: bool = True) -> None:
    """Add the table's flags of the options ``names`` to an argparse parser. Every flag defaults to
    None (unset: a prim's ``dftl:`` attribute, a quality preset or the table's default decides)
    except those with no other source (``--device``). ``choices`` maps an option name to the
    choices a higher layer knows live (the solver registry)."""
    for name in names:
        o = OPTIONS[name]
        if choices and name in choices:
            o = replace(o, choices=tuple(choices[name]))
        kw: dict = {"dest": o.cli.lstrip("-").replace("-", "_")}
        if o.metavar:
            kw["metavar"] = o.metavar
        if o.repeat:
            kw["action"] = "append"
        elif o.choices:
            kw["choices"] = o.choices
        elif o.type in (int, float) and (o.low is not None or o.high is not None or o.limit is not None):
            kw["type"] = _cli_type(o)
        elif o.type is int:
            kw["type"] = int
        default_text = None
        if o.usd and defaults_from_usd and o.default is not None:
            default_text = f"{o.usd}, else {_num(o.default) if isinstance(o.default, float) else o.default}"
        kw["help"] = cli_help(o, default_text).replace("%", "%%")  # argparse formats help with %
        parser.add_argument(o.cli, **kw)


# -- output options (issue 21: docs/caches.md); appended: they are not SimulationOptions fields, so
# -- simulate_usd and the batch jobs take them off before making the SimulationOptions
#: the metrics a ``--check`` gate may name (dftl_warp.output.qc.METRICS)
QC_METRICS = ("stretch", "penetration", "speed", "energy", "nan")
_OUTPUT = [
    Option("no_velocities", bool, False, "write no velocities (points and extent only)",
           cli="--no-velocities", toml="no_velocities", api="no_velocities"),
    Option("frame_step", int, 1, "write every Nth frame (every frame is simulated)", low=1,
           cli="--frame-step", metavar="N", toml="frame_step", api="frame_step"),
    Option("check", str, None,
           "QC gates, e.g. 'stretch<1e-3,penetration<0.05': a frame and prim breaking one fails the "
           "run with exit status 3 and no output (metrics: " + ", ".join(QC_METRICS) + ")",
           pattern=re.compile(r"^(\s*(" + "|".join(QC_METRICS) + r")\s*<\s*[-+0-9.eE]+\s*)(,\s*(" + "|".join(QC_METRICS)
                              + r")\s*<\s*[-+0-9.eE]+\s*)*$"),
           cli="--check", metavar="GATES", toml="check", api="check"),
    Option("clips", int, None,
           "write USD value clips of FRAMES frames each (0 or no value: chosen by size), written in parallel",
           low=0, cli="--clips", metavar="FRAMES", toml="clips", api="clips"),
    Option("no_clips", bool, False,
           "write one layer, never value clips (without --clips, large outputs are written as clips: docs/caches.md)",
           cli="--no-clips", toml="no_clips", api="no_clips"),
]
for _o in _OUTPUT:
    OPTIONS[_o.name] = _o
    BY_TOML[_o.toml] = _o
    BY_API[_o.api] = _o
#: the output options' names (not fields of SimulationOptions)
OUTPUT_OPTIONS = tuple(o.name for o in _OUTPUT)

# -- clean starts (issue 20: docs/features.md); appended: run options, fields of SimulationOptions
_CLEAN_START = [
    Option("preroll", float, 0.0,
           "settle the groom at the first frame's pose for this long before the shot (hair inside a "
           "collider is moved out first; the preroll goes on, up to 8x as long (whole frames), until the groom is "
           "settled); 0: no preroll", unit="s", low=0.0, limit=MAX_PREROLL,
           cli="--preroll", metavar="SECONDS", toml="preroll", api="preroll"),
]
for _o in _CLEAN_START:
    OPTIONS[_o.name] = _o
    BY_TOML[_o.toml] = _o
    BY_API[_o.api] = _o


# -- --tolerance (issue 19: dftl_warp/simulation/tolerance.py); appended: not a SimulationOptions field, so
# -- simulate_usd takes it off and hands it to the Simulation. Not a USD attribute, not (yet) a batch key.
_TOLERANCE = Option(
    "tolerance", float, None,
    "target accuracy: the RMS position error the run may make (stage units); substeps per frame (and the "
    "solver, where --solver is unset) are chosen from a step-doubling estimate on a sample of strands "
    "(overrides --substeps)", unit="stage units", low=0.0, low_open=True,
    cli="--tolerance", metavar="LENGTH", api="tolerance")
OPTIONS[_TOLERANCE.name] = _TOLERANCE
BY_API[_TOLERANCE.api] = _TOLERANCE


# -- guides and render strands (issue 22: docs/guides.md); appended: not SimulationOptions fields, so
# -- simulate_usd takes them off and hands them to the Simulation. dftl:guides is read by dftl_warp.usd.guides.
_GUIDES = [
    Option("guides", str, None,
           "pick N guide strands (an integer, a fraction such as 0.1, or a percentage such as 10%) from each "
           "BasisCurves prim without dftl:guides, simulate only those and deform the rest from them",
           pattern=re.compile(r"^(\d+|\d*\.\d+|\d+(\.\d+)?%|\d*\.\d+%)$"),
           cli="--guides", metavar="N|FRACTION", api="guides"),
    Option("guide_method", str, "kmeans", "how --guides picks the guides", choices=("kmeans", "fps"),
           cli="--guide-method", metavar="METHOD", api="guide_method"),
    Option("guides_output", str, "curves",
           "what is written for guide-driven render curves: curves (the deformed curves as time samples) or "
           "binding (the guides only, plus the binding as primvars for render-time deformation)",
           choices=("curves", "binding"), cli="--guides-output", metavar="WHAT", api="guides_output"),
    Option("guidesRel", "rel", None,
           "the guide BasisCurves prim(s) that drive this render prim: it is deformed from them, not simulated",
           usd="dftl:guides", scope="curves"),
]
for _o in _GUIDES:
    OPTIONS[_o.name] = _o
    if _o.api:
        BY_API[_o.api] = _o
    if _o.usd:
        BY_USD[_o.usd] = _o
#: the guide options' Python keywords (not fields of SimulationOptions)
GUIDE_OPTIONS = ("guides", "guide_method", "guides_output")
