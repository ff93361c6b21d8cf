"""The small base every solver implements, and the registry that names them.

A solver advances a :class:`~dftl_warp.core.state.State` by substeps of ``dt`` seconds:

- ``state()``: a rest State with exactly the arrays the solver needs;
- ``step(state_in, state_out, control, dt, root_alpha=1.0)``: one substep (``state_out`` may be
  ``state_in``), roots ``root_alpha`` in [0, 1] of the way along ``control``'s root path (from
  its start to its end targets: linear, or the C1 Hermite curve of :class:`~dftl_warp.core.state.Control`);
- ``advance(state, control, dt, substeps)``: a frame's substeps in place, roots moving along that
  path (on CUDA captured once in a CUDA graph and replayed);
- ``diagnostics(state)``: energy per unit particle mass (J/kg), max relative stretch, max speed (m/s).

A new solver subclasses :class:`Solver`, decorates itself with :func:`register`, and is imported
by ``dftl_warp/solvers/__init__.py`` (one line). :func:`make_solver` builds one by name, passing
the options the class lists in ``options``.

Arguments are checked in Python before anything launches (:func:`check_step`): a NaN, infinite,
zero or negative ``dt``, a ``substeps`` that is not an integer >= 1, a ``root_alpha`` outside
[0, 1] and a non-finite ``gravity`` raise ValueError naming the argument; a State or Control that
is not the solver's model's (:func:`check_bound`: another model's arrays would be indexed past
their end by the kernels) raises TypeError or ValueError naming it. Every subclass's ``step``,
``advance`` and ``diagnostics`` are wrapped with the checks (:meth:`Solver.__init_subclass__`), so a
new solver gets them without a line of its own; they cost a few comparisons per call, nothing on
the device.

The results are not checked: ``advance`` and ``step`` never read the device back (on CUDA they
only launch), so a setting that blows up (a ``dt`` far beyond the solver's stable range: the pbd
solver at dt = 1e6 s flies off to 1e13 m) is silent here. ``diagnostics(state)`` measures a State
(its stretch and speed infinite, its energy NaN, when it is not finite); the :class:`~dftl_warp.simulation.simulate.Simulation` (its energy
monitor, :mod:`dftl_warp.simulation.monitor`) and
:func:`~dftl_warp.simulation.strands.simulate_strands`, which read the state back anyway, warn with
an :class:`~dftl_warp.simulation.monitor.EnergyGrowthWarning` when it is not finite (and
``simulate_strands`` when a particle lies beyond 100 strand lengths from its root).
"""

from __future__ import annotations

import functools
import math
import numbers
import warnings

import numpy as np
import warp as wp

from ..kernels.solvers.diagnostics import strand_diagnostics_kernel
from ..options import add_choice, default, did_you_mean
from ..checks import check_lengths

#: standard gravity, m/s^2, along -Y (the default up axis)
DEFAULT_GRAVITY = (0.0, -9.81, 0.0)

#: solver classes by name, in registration order (:func:`register`)
SOLVERS: dict[str, type] = {}


_UNSET = object()


def check_step(dt, substeps=_UNSET) -> None:
    """ValueError naming the argument unless ``dt`` is a finite number > 0 (seconds) and
    ``substeps`` (when given, None included) an integer >= 1."""
    if isinstance(dt, (bool, np.bool_)) or not isinstance(dt, numbers.Real) or not (math.isfinite(dt) and dt > 0):
        raise ValueError(f"dt must be a finite number of seconds > 0, got {dt!r}")
    if substeps is not _UNSET and (isinstance(substeps, (bool, np.bool_))
                                   or not isinstance(substeps, numbers.Integral) or substeps < 1):
        raise ValueError(f"substeps must be an integer >= 1, got {substeps!r}")


def check_root_alpha(root_alpha) -> None:
    """ValueError unless ``root_alpha`` is a finite number in [0, 1] (a NaN put every root, and
    so every particle, at NaN)."""
    ok = (not isinstance(root_alpha, (bool, np.bool_)) and isinstance(root_alpha, numbers.Real)
          and 0.0 <= root_alpha <= 1.0)
    if not ok:
        raise ValueError(f"root_alpha must be a number in [0, 1] (the share of the frame's root path), "
                         f"got {root_alpha!r}")


def check_bound(model, state, control=_UNSET, name: str = "state") -> None:
    """TypeError or ValueError naming ``name`` unless ``state`` is a State whose arrays are the
    ``model``'s (length ``num_slots``, its precision, its device), and ``control`` (when given) a
    Control made by this model (``model.control()``). A State or Control of another model was
    stepped without a word: its arrays were read and written past their ends."""
    from ..core.state import Control, State

    if not isinstance(state, State):
        raise TypeError(f"{name} must be a dftl_warp.State (solver.state()), got {type(state).__name__}")
    for field in ("positions", "velocities", "corrections"):
        a = getattr(state, field)
        if a is not None and (a.shape[0] != model.num_slots or a.dtype != model.vec3 or a.device != model.device):
            raise ValueError(
                f"{name}.{field} is not this model's ({a.shape[0]} slots of {wp.types.type_repr(a.dtype)} on "
                f"{a.device}; the model has {model.num_slots} of {wp.types.type_repr(model.vec3)} on "
                f"{model.device}): make States with this solver's state()")
    made_for = state.layout
    if made_for is not None and made_for is not model.layout and not _same_layout(made_for, model.layout):
        # as many slots, other strands: the points were cut into this model's strands without a word
        raise ValueError(f"{name} was made by another model (other strands in as many slots): make States with "
                         f"this solver's state()")
    if control is _UNSET:
        return
    if not isinstance(control, Control):
        raise TypeError(f"control must be a dftl_warp.Control (model.control()), got {type(control).__name__}")
    if control.model is not model:
        raise ValueError("control was made by another model: make it with this solver's model.control()")


def _same_layout(a, b) -> bool:
    """Whether layouts ``a`` and ``b`` put the same strands in the same slots (models rebuilt from
    the same strands share States)."""
    return all(np.array_equal(getattr(a, k), getattr(b, k))
               for k in ("strand_order", "strand_base", "strand_stride", "strand_count"))


def check_gravity(gravity, precision: str = "float64") -> np.ndarray:
    """``gravity`` as a (3,) float64 array; ValueError naming it unless it is 3 finite numbers,
    each small enough for a float32 ``precision`` (1e39 became inf in the model, the positions NaN)."""
    try:
        g = np.asarray(gravity, dtype=np.float64).reshape(3)
    except (TypeError, ValueError):
        raise ValueError(f"gravity must be 3 finite numbers (an acceleration), got {gravity!r}") from None
    if not np.isfinite(g).all():
        raise ValueError(f"gravity must be 3 finite numbers (an acceleration), got {tuple(g.tolist())}")
    if precision == "float32":
        check_lengths(g, "gravity", "", error=ValueError)
    return g


def check_model(model, name: str = "model") -> None:
    """TypeError naming ``name`` unless ``model`` is a dftl_warp Model (None, an array of points
    or a Scene failed later with an AttributeError that named none of them)."""
    from ..core.model import Model

    if not isinstance(model, Model):
        raise TypeError(f"{name} must be a dftl_warp Model (Model.from_strands, simulate's scene), "
                        f"got {'None' if model is None else type(model).__name__}")


def check_no_features(model, solver: str) -> None:
    """ValueError naming the model's feature flags for a solver that steps gravity and roots only
    (a model with colliders, drag, wind or hair-hair stepped by it ignored them without a word).
    Root binding has no flag: it only sets root targets, which every solver follows."""
    if model.feature_flags:
        raise ValueError(f"the {solver} solver steps gravity and roots only; this model has features "
                         f"({', '.join(sorted(model.feature_flags))}): use --solver dftl")


def check_real(name: str, value, *, minimum: float = 0.0, inclusive: bool = False) -> float:
    """``value`` as a float; ValueError naming ``name`` unless it is a finite real number above
    ``minimum`` (at or above it where ``inclusive``)."""
    ok = not isinstance(value, (bool, np.bool_)) and isinstance(value, numbers.Real) and math.isfinite(value)
    if not ok or not (value >= minimum if inclusive else value > minimum):
        raise ValueError(f"{name} must be {'>=' if inclusive else '>'} {minimum:g} and finite, got {value!r}")
    return float(value)


def check_damping(damping) -> float:
    """``damping`` as a float; ValueError unless it is a number in [0, 1] (a string or a bool was
    taken through float() by some solvers)."""
    if isinstance(damping, (bool, np.bool_)) or not isinstance(damping, numbers.Real) or not 0 <= damping <= 1:
        raise ValueError(f"damping must be in [0, 1], got {damping!r}")
    return float(damping)


def check_integer(name: str, value, *, minimum: int = 1) -> int:
    """``value`` as an int; ValueError naming ``name`` unless it is an integer >= ``minimum``."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Integral) or value < minimum:
        raise ValueError(f"{name} must be an integer >= {minimum}, got {value!r}")
    return int(value)


def check_bool(name: str, value) -> bool:
    """``value`` as a bool; ValueError naming ``name`` unless it is True or False."""
    if not isinstance(value, (bool, np.bool_)):
        raise ValueError(f"{name} must be True or False, got {value!r}")
    return bool(value)


def _checked_init(init):
    @functools.wraps(init)
    def checked(self, model, *args, **kwargs):
        check_model(model)
        return init(self, model, *args, **kwargs)

    checked._checked = True
    return checked


def _checked_step(step):
    @functools.wraps(step)
    def checked(self, state_in, state_out, control, dt, root_alpha=1.0, *args, **kwargs):
        check_step(dt)
        check_root_alpha(root_alpha)
        check_bound(self.model, state_in, control, "state_in")
        if state_out is not state_in:
            check_bound(self.model, state_out, name="state_out")
        return step(self, state_in, state_out, control, dt, root_alpha, *args, **kwargs)

    checked._checked = True
    return checked


def _checked_advance(advance):
    @functools.wraps(advance)
    def checked(self, state, control, dt, substeps, *args, **kwargs):
        check_step(dt, substeps)
        check_bound(self.model, state, control)
        return advance(self, state, control, dt, substeps, *args, **kwargs)

    checked._checked = True
    return checked


def _checked_diagnostics(diagnostics):
    @functools.wraps(diagnostics)
    def checked(self, state, *args, **kwargs):
        check_bound(self.model, state)
        return diagnostics(self, state, *args, **kwargs)

    checked._checked = True
    return checked


def register(cls):
    """Class decorator: make ``cls`` available to :func:`make_solver` under ``cls.name``."""
    if not cls.name or cls.name in SOLVERS:
        raise ValueError(f"solver name {cls.name!r} is empty or taken")
    SOLVERS[cls.name] = cls
    add_choice("solver", cls.name)  # the options table (--solver, dftl:solver, TOML) accepts it
    return cls


class Solver:
    """Base of the solvers: the shared ``state``, ``advance`` and ``diagnostics``.

    Subclasses set :attr:`name` and :attr:`options` and implement :meth:`step`; they may
    override :meth:`advance` (fused substeps) and :meth:`kernels` (what a CUDA graph captures).
    """

    #: registry name
    name = ""
    #: keyword options :func:`make_solver` passes on (besides ``gravity``); others are dropped
    options: tuple[str, ...] = ()

    def __init_subclass__(cls, **kwargs):
        """Wrap the subclass's own ``__init__`` (:func:`check_model`), ``step``, ``advance`` and
        ``diagnostics`` with the checks (:func:`check_step`, :func:`check_root_alpha`, :func:`check_bound`)."""
        super().__init_subclass__(**kwargs)
        for name, wrap in (("__init__", _checked_init), ("step", _checked_step), ("advance", _checked_advance),
                           ("diagnostics", _checked_diagnostics)):
            method = cls.__dict__.get(name)
            if method is not None and not getattr(method, "_checked", False):
                setattr(cls, name, wrap(method))

    def __init__(self, model, *, gravity=DEFAULT_GRAVITY):
        check_model(model)
        self._model = model
        self.gravity = model.vec3(*check_gravity(gravity, model.precision))
        self._graphs: dict = {}

    @property
    def model(self):
        """The Model this solver was built for; fixed (its arrays were cached per model)."""
        return self._model

    @model.setter
    def model(self, value):
        raise AttributeError("a solver's model is fixed at construction: make a new solver for another model")

    @staticmethod
    def carries(correction: str) -> bool:
        """Whether the solver keeps the prior form's corrections in its States."""
        return False

    @property
    def carries_corrections(self) -> bool:
        return False

    def state(self):
        """A rest State with exactly the arrays this solver needs."""
        return self.model.state(with_corrections=self.carries_corrections)

    def step(self, state_in, state_out, control, dt: float, root_alpha: float = 1.0) -> None:
        raise NotImplementedError

    def kernels(self) -> list:
        """The kernels :meth:`advance` launches (compiled before a CUDA graph captures them)."""
        return []

    def substeps(self, state, control, dt: float, substeps: int) -> None:
        """The frame's substeps as launches (what :meth:`advance` captures on CUDA)."""
        real = np.dtype(self.model.precision).type  # alpha rounded as the fused kernels compute it
        for k in range(substeps):
            self.step(state, state, control, dt, float(real(k + 1) / real(substeps)))

    def advance(self, state, control, dt: float, substeps: int) -> None:
        """``substeps`` steps of ``dt`` (s) in place, roots moving along the Control's root path.

        On CUDA the substeps are captured once per (state, control, dt, substeps) in a CUDA graph
        and replayed afterwards, and ``advance`` returns before the device is done. The arguments
        are checked; the results are not checked: a blow-up (non-finite or absurd positions from a ``dt`` far
        beyond the stable range) is silent here; :meth:`diagnostics` measures it, and
        ``Simulation`` and ``simulate_strands`` warn of blown-up states (module docstring).
        """
        check_step(dt, substeps)
        check_bound(self.model, state, control)
        m = self.model
        if m.num_strands == 0:
            return
        self.launch_frame(state, control, dt, substeps, lambda: self.substeps(state, control, dt, substeps),
                          self.kernels)

    def graph_variant(self) -> tuple:
        """What else a frame's CUDA graph depends on: the host scalars its launches pass that can change
        between frames (a graph replays the values it was captured with)."""
        return ()

    def launch_frame(self, state, control, dt: float, substeps: int, run, kernels, variant=()) -> None:
        """``run()`` directly on the CPU; on CUDA through a graph cached per (state, control, dt,
        substeps, ``variant``: what else picks the kernels), the kernels that ``kernels()`` lists
        compiled before the capture."""
        m = self.model
        if not m.device.is_cuda:
            run()
            return
        # the solver's own host scalars, and the features' (the meshes interpolated per substep: their
        # launches are in the graph)
        variant = (*variant, *self.graph_variant(), *getattr(control.features, "graph_variant", tuple)())
        key = (id(state), id(control), float(dt), int(substeps), *variant)
        graph = self._graphs.get(key)
        if graph is None:
            for kernel in kernels():
                kernel.module.load(m.device)
            with wp.ScopedCapture(device=m.device) as capture:
                run()
            graph = self._graphs[key] = capture.graph
        wp.capture_launch(graph)

    def diagnostics(self, state) -> dict:
        """Total energy per unit particle mass (J/kg), max relative stretch, max speed (m/s); the
        stretch and speed are infinite (and the energy NaN) when a position or velocity is not finite."""
        check_bound(self.model, state)
        m = self.model
        n = m.num_strands
        if n == 0:
            return {"energy": 0.0, "max_stretch": 0.0, "max_speed": 0.0}
        out = [wp.zeros(n, dtype=wp.float64, device=m.device) for _ in range(3)]
        wp.launch(
            strand_diagnostics_kernel(m.scalar),
            dim=n,
            inputs=[m.strand_base, m.strand_stride, m.strand_count, m.rest_lengths, self.gravity,
                    state.positions, state.velocities],
            outputs=out,
            device=m.device,
        )
        energy, stretch, speed = (a.numpy() for a in out)
        # potential energy is measured from the device origin; shift it back to world space
        g = np.array(self.gravity, dtype=np.float64)
        free = float(np.sum(np.maximum(m.counts - 1, 0)))
        return {
            "energy": float(energy.sum() - free * g @ m.origin),
            "max_stretch": float(stretch.max()),
            "max_speed": float(speed.max()),
        }


#: the solver options a run may be given, and what each sets (:func:`unused_solver_options`)
SOLVER_OPTION_TEXT = {"iterations": "Gauss-Seidel iterations", "damping": "damping (DFTL's s)",
                      "correction": "correction form"}


def unused_solver_options(options: dict, solvers, flag=str, subject: str = "no prim runs") -> list[str]:
    """One warning per solver option in ``options`` that no solver in ``solvers`` takes (``--damping
    0.5`` with ``--solver pbd`` did nothing without a word): ``iterations`` whenever given,
    ``damping`` and ``correction`` where they differ from the default (which a quality preset fills
    in). ``flag(name)`` spells the option as the caller's user wrote it."""
    out = []
    for name, what in SOLVER_OPTION_TEXT.items():
        value = options.get(name)
        takers = [n for n, c in SOLVERS.items() if name in c.options]
        if value is None or set(solvers) & set(takers) or (name != "iterations" and value == default(name)):
            continue
        names = " or ".join([", ".join(takers[:-1]), takers[-1]] if len(takers) > 2 else takers)
        out.append(f"{flag(name)} {value} does nothing here: {subject} the {names} solver, whose {what} it sets "
                   f"({', '.join(sorted(solvers))})")
    return out


def solver_class(solver: str):
    """The class registered as ``solver``; ValueError naming the choices otherwise."""
    try:
        return SOLVERS[solver]
    except KeyError:
        raise ValueError(f"unknown solver {solver!r}; choose one of {', '.join(SOLVERS)}") from None


def carries_corrections(solver: str, correction: str) -> bool:
    """Whether the solver named ``solver`` keeps the prior form's corrections in its States."""
    return solver_class(solver).carries(correction)


def make_solver(model, solver: str = "dftl", **options):
    """A solver by registry name (:data:`SOLVERS`), given the options its class lists
    (``gravity`` always); options that do not apply to it (``damping`` and ``correction`` for pbd
    and reference, ``iterations`` for all but pbd) are dropped with a UserWarning each (as
    :func:`~dftl_warp.simulation.strands.simulate_strands` warns; a default damping or correction
    stays quiet). A name that no registered solver knows (a typo such as ``dampnig``) raises
    TypeError with the closest known name."""
    cls = _solver_for(model, solver, options)
    dropped = {k: v for k, v in options.items() if k != "gravity" and k not in cls.options}
    lines = unused_solver_options(dropped, {solver}, subject="this solver is not")
    for k, v in dropped.items():
        if k not in SOLVER_OPTION_TEXT and v is not None:
            takers = [n for n, c in SOLVERS.items() if k in c.options]
            lines.append(f"{k} {v!r} does nothing here: the {solver} solver does not take it (only {', '.join(takers)})")
    for line in lines:
        warnings.warn(line, UserWarning, stacklevel=2)
    return build_solver(model, solver, **options)


def build_solver(model, solver: str = "dftl", **options):
    """:func:`make_solver` without its warnings, for callers that warn about the dropped options
    themselves (simulate_strands, simulate: one warning per run, not per group)."""
    cls = _solver_for(model, solver, options)
    kept = {k: v for k, v in options.items() if k == "gravity" or k in cls.options}
    return cls(model, **kept)


def _solver_for(model, solver: str, options: dict):
    """The class of ``solver``, after make_solver's checks of ``model`` and the option names."""
    from ..core.model import Model

    if not isinstance(model, Model):
        raise TypeError(f"make_solver: model must be a dftl_warp.Model (Model.from_strands, simulate's scene), "
                        f"got {type(model).__name__}")
    cls = solver_class(solver)
    known = {"gravity"}.union(*(c.options for c in SOLVERS.values()))
    for k in options:
        if k not in known:
            raise TypeError(f"make_solver: unknown keyword {k!r} for any solver{did_you_mean(k, sorted(known))}")
    return cls
