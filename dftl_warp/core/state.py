"""Time-varying simulation data: :class:`State` (per particle) and :class:`Control` (per strand).

States are swapped between steps (``solver.step(state_in, state_out, ...)``); a step may also run
in place with ``state_in is state_out``.
"""

from __future__ import annotations

import functools
import math
import numbers
from dataclasses import dataclass, field

import numpy as np
import warp as wp


FIELDS = ("positions", "velocities", "corrections")

#: how a model's features become device data and per-frame controls: ``build(model_args, features,
#: widths=)`` (Model.from_strands) and ``control(model)`` (Control.at_rest), installed by
#: :mod:`dftl_warp.features` when it is imported (the feature objects come from there, so it is
#: whenever a model has features): the core does not import the features, which sit above it
FEATURE_HOOKS: dict = {}


def install_feature_hooks(*, build, control) -> None:
    """Install the features' builders (:func:`dftl_warp.features.step.build`,
    :class:`dftl_warp.features.step.FeatureControl`)."""
    FEATURE_HOOKS.update(build=build, control=control)


def feature_hook(name: str):
    """The installed feature hook ``name`` (``"build"`` or ``"control"``)."""
    hook = FEATURE_HOOKS.get(name)
    if hook is None:
        raise ValueError("features need dftl_warp.features imported (their objects come from there)")
    return hook


@dataclass(eq=False)
class State:
    """Particle state in the model's layout, relative to ``model.origin``.

    positions: m; velocities: m/s; corrections: m, the prior form's carried ``x - p`` of the last
    step, a push scaled down by the step's motion (``kernels/solvers/ftl.py``, ``carried_func``;
    ``None`` when the solver does not carry it).

    When the model's layout interleaves its state vectors (:mod:`dftl_warp.core.layout`), the three
    arrays are views of one ``storage`` buffer, offset by 32 and 64 slots: each view's slots past
    a chunk's 32 entries belong to the other fields. Kernels index them through the layout and
    never notice. A view's own ``assign``, ``zero_`` and ``fill_`` write only its field's slots
    (through :meth:`write`), so ``state.velocities.assign(model.points_to_device(v))`` sets the
    velocities on every layout; ``wp.copy`` into a view cannot be caught and would write the other
    fields' slots too: copy whole States with :meth:`assign`.
    """

    positions: wp.array
    velocities: wp.array
    corrections: wp.array | None
    #: the buffer the fields are views of (interleaved layouts), else None
    storage: wp.array | None = None
    #: the layout of the model that made it (None: unknown), checked against a solver's model
    layout: object = field(default=None, repr=False)

    def __post_init__(self):
        if self.storage is None:
            for name in FIELDS:
                view = getattr(self, name)
                if view is not None:   # a short array filled the first rows, the rest kept their values
                    view.assign = functools.partial(self.write, name)
            return
        for name in FIELDS:
            view = getattr(self, name)
            if view is not None:   # the view's whole-array writes keep to the field's own slots
                view.assign = functools.partial(self.write, name)
                view.zero_ = functools.partial(self.write, name, None, zero=True)
                view.fill_ = functools.partial(self._fill, name)

    @classmethod
    def at_rest(cls, model, *, with_corrections: bool = True) -> State:
        if model.rest_positions is None:
            raise ValueError("this model has no host rest positions (a synthetic groom built on the device); "
                             "copy an existing State with State.clone() instead")
        lay = model.layout
        if lay.interleave > 1:
            # the rest positions are zero outside the position slots: the other fields start at zero
            host = np.zeros((lay.storage_length, 3), dtype=model.rest_positions.dtype)
            host[:lay.num_slots] = model.rest_positions
            return cls.interleaved(wp.array(host, dtype=model.vec3, device=model.device), lay, with_corrections)

        def zeros():
            return wp.zeros(model.num_slots, dtype=model.vec3, device=model.device)

        return cls(
            positions=wp.array(model.rest_positions, dtype=model.vec3, device=model.device),
            velocities=zeros(),
            corrections=zeros() if with_corrections else None,
            layout=lay,
        )

    @classmethod
    def interleaved(cls, storage: wp.array, layout, with_corrections: bool) -> State:
        """The State whose fields are views of ``storage`` in the interleaved ``layout``."""
        fields = 3 if with_corrections else 2
        if layout.interleave < fields:
            raise ValueError(f"the layout interleaves {layout.interleave} state vectors; this State needs {fields}")
        return cls._views(storage, layout.num_slots, with_corrections, layout)

    @classmethod
    def _views(cls, storage: wp.array, n: int, with_corrections: bool, layout=None) -> State:
        """Fields as ``n``-slot views of ``storage``, 32 slots apart."""
        views = [storage[32 * f: 32 * f + n] for f in range(3 if with_corrections else 2)]
        return cls(positions=views[0], velocities=views[1], corrections=views[2] if with_corrections else None,
                   storage=storage, layout=layout)

    def clone(self) -> State:
        """A copy of this state in new device arrays."""
        if self.storage is not None:
            return State._views(wp.clone(self.storage), self.positions.shape[0], self.corrections is not None,
                                self.layout)
        return State(positions=wp.clone(self.positions), velocities=wp.clone(self.velocities),
                     corrections=None if self.corrections is None else wp.clone(self.corrections), layout=self.layout)

    def assign(self, other: State) -> None:
        """Copy ``other`` into this state (same model)."""
        if (self.storage is None) != (other.storage is None):
            raise ValueError("cannot assign between an interleaved and a plain State")
        if self.storage is not None:
            wp.copy(self.storage, other.storage)
            if self.corrections is not None and other.corrections is None:
                self.write("corrections", None, zero=True)
            return
        wp.copy(self.positions, other.positions)
        wp.copy(self.velocities, other.velocities)
        if self.corrections is not None:
            if other.corrections is not None:
                wp.copy(self.corrections, other.corrections)
            else:
                self.corrections.zero_()

    def write(self, field: str, values, *, layout=None, zero: bool = False) -> None:
        """Set ``field`` (``"positions"``, ``"velocities"`` or ``"corrections"``) from ``values``,
        a (num_slots, 3) array in the layout's slot order (``Model.points_to_device``) or a device
        array of that shape, or to zero.

        Plain States assign the array; interleaved ones write only the field's own slots, leaving
        the other fields untouched: the slots follow from the storage. ``layout`` is ignored; it is
        accepted for callers written when it was needed (scripts/bench_features.py)."""
        target = getattr(self, field)
        if target is None:
            raise ValueError(f"this State has no {field}")
        n = target.shape[0]
        shape = values.shape if isinstance(values, wp.array) else np.shape(values)
        if not zero and (shape[:1] != (n,) if isinstance(values, wp.array) else int(np.prod(shape)) != 3 * n):
            raise ValueError(f"{field} must have shape ({n}, 3) (num_slots, in the layout's slot order: "
                             f"Model.points_to_device), got {tuple(shape)}")
        if self.storage is None:
            target.zero_() if zero else type(target).assign(target, values)
            return
        if not zero:
            values = values.numpy() if isinstance(values, wp.array) else np.asarray(values)
            values = values.reshape(target.shape[0], -1)
        self._write_own(field, 0.0 if zero else values)

    def _fill(self, field: str, value) -> None:
        """``view.fill_(value)`` of an interleaved field: every slot of the field set to ``value``."""
        self._write_own(field, np.asarray(value.numpy() if isinstance(value, wp.array) else value))

    def _write_own(self, field: str, values) -> None:
        """Write ``values`` (per view entry, or one value) into ``field``'s own slots of the storage:
        view entry ``i`` is storage slot ``32 f + i``, the field's own where ``i`` mod the chunk
        (32 slots per interleaved vector) is below 32."""
        f = FIELDS.index(field)
        n = getattr(self, field).shape[0]
        own = np.flatnonzero(np.arange(n) % (32 * self._interleave()) < 32)
        host = self.storage.numpy()
        values = np.asarray(values)
        host[32 * f + own] = values[own] if values.ndim == 2 and values.shape[0] == n else values
        self.storage.assign(host)

    def _interleave(self) -> int:
        """State vectors per chunk of the storage (from the views' offsets and the buffer length)."""
        return (self.storage.shape[0] - self.positions.shape[0]) // 32 + 1

    def bytes_per_particle(self, num_points: int | None = None) -> int:
        """Device bytes of the state per particle (``num_points``; default: per slot)."""
        n = max(self.positions.shape[0] if num_points is None else int(num_points), 1)
        if self.storage is not None:
            return int(self.storage.capacity // n)
        arrays = [a for a in (self.positions, self.velocities, self.corrections) if a is not None]
        return int(sum(a.capacity for a in arrays) // n)


#: frames in the difference stencil of :func:`frame_velocity` (fourth order)
VELOCITY_STENCIL = 5


@functools.cache
def stencil_weights(offsets: tuple) -> tuple:
    """Weights ``w`` (exact fractions, as floats) of the finite difference ``sum w_k x(offset_k)``
    that is the derivative at offset 0 (per unit of offset) of the polynomial through the points:
    the derivatives at 0 of the Lagrange basis polynomials of the integer ``offsets``."""
    from fractions import Fraction

    out = []
    for k, ok in enumerate(offsets):
        total = Fraction(0)
        for m, om in enumerate(offsets):
            if m == k:
                continue
            term = Fraction(1, ok - om)
            for j, oj in enumerate(offsets):
                if j not in (k, m):
                    term *= Fraction(-oj, ok - oj)
            total += term
        out.append(float(total))
    return tuple(out)


def frame_velocity(points_at, frame: int, first: int, last: float, frame_duration: float) -> np.ndarray:
    """Velocity (units/s) at ``frame`` of points sampled once a frame (``points_at(f)``: (..., 3))
    in a shot of frames ``first .. last``: the fourth-order difference over the 5 frames around it,
    ``(x[f-2] - 8 x[f-1] + 8 x[f+1] - x[f+2]) / 12T`` inside the shot, the 5-frame window moved to
    fit inside it near its ends (one-sided at them, e.g. ``(-25 x[f] + 48 x[f+1] - 36 x[f+2] +
    16 x[f+3] - 3 x[f+4]) / 12T`` at the first frame); fewer frames in a shorter shot (three give
    Catmull-Rom's central difference, two the chord, one zero). ``T`` is ``frame_duration`` (s).
    A still point gets zero and a point moving at constant velocity that velocity, to round-off.

    Why fourth order (docs/elastic.md, velocities): on a sinusoid of angular frequency w the
    second-order central difference (Catmull-Rom's) is ``sin(wT) / wT`` of the velocity, 1.1 % low
    at 1 Hz and 24 fps, and a hair's motion relative to its moving root (what its written local
    velocity is) is often smaller than that error of the root's; the fourth-order one is low by
    ``(wT)^4 / 30``, 1.6e-4 there."""
    span = int(min(VELOCITY_STENCIL, last - first + 1))
    lo = int(min(max(frame - VELOCITY_STENCIL // 2, first), last - span + 1))
    here = np.asarray(points_at(frame), dtype=np.float64)
    total = np.zeros_like(here)
    # sum w_k (x_k - x_f): the weights sum to zero, so a still point gets exactly zero
    for w, f in zip(stencil_weights(tuple(range(lo - frame, lo - frame + span))), range(lo, lo + span)):
        if w != 0.0 and f != frame:
            total += w * (np.asarray(points_at(f), dtype=np.float64) - here)
    return total / float(frame_duration)


class AbsentFeatures:
    """``control.features`` of a model built without features, and the base of the features' own
    (:class:`~dftl_warp.features.step.FeatureControl`): what a frame loop calls on it, answered for
    the features the model lacks, so that one loop runs any model.

    Without colliders no collider poses are right (there is nothing to move; any pose is a
    ValueError naming what is missing, as are mesh points); without wind the frame time is checked
    and does nothing: it drives only the wind's keyframes and noise, and a model without a Wind
    feature has no wind data it could leave unused (a loop may set it whatever the model);
    :meth:`set_wind` and :meth:`bound_roots` are ValueErrors naming the feature they need."""

    colliders = air = wind = binding = None
    pose_start = pose_end = pose = pose_prev = inv_pose = inv_pose_prev = None
    wind_velocity = wind_time = None

    def set_collider_poses(self, start, end=None, **rates) -> None:
        """Poses of the model's colliders: none here (an empty array, or ``[]``)."""
        given = max(np.size(start), 0 if end is None else np.size(end))
        if given:
            raise ValueError(f"set_collider_poses: the model has no colliders (no Colliders feature with shapes "
                             f"was given to Model.from_strands), so it takes no poses; got {np.shape(start)}")

    def resync(self) -> None:
        """Nothing to forget without colliders."""

    def set_mesh_points(self, index: int, points) -> None:
        raise ValueError(f"set_mesh_points: collider {index} is not a mesh: the model has no colliders (no Colliders "
                         "feature with shapes was given to Model.from_strands)")

    def set_frame_time(self, start: float, end: float) -> None:
        """The frame spans ``start`` -> ``end`` seconds. ValueError unless both are finite numbers of
        seconds and ``end`` is not before ``start``."""
        for name, t in (("start", start), ("end", end)):
            if isinstance(t, (bool, np.bool_)) or not isinstance(t, numbers.Real) or not math.isfinite(t):
                raise ValueError(f"set_frame_time: {name} must be a finite number of seconds, got {t!r}")
        if end < start:
            raise ValueError(f"set_frame_time: end {end!r} s is before start {start!r} s")

    def set_wind(self, start, end=None) -> None:
        raise ValueError("set_wind: the model has no Wind feature (give features=[Drag(...), Wind(...)] to "
                         "Model.from_strands)")

    def bound_roots(self, start, end=None) -> tuple:
        raise ValueError("the model has no RootBinding feature")


@dataclass(eq=False)
class Control:
    """Kinematic root targets per device strand, relative to ``model.origin`` (m), and the root's
    path inside the frame.

    Across a frame of ``frame_duration`` seconds a root moves from ``root_start`` to ``root_end``
    on the cubic Hermite curve with the root's velocities at the frame's ends as tangents
    (:mod:`dftl_warp.kernels.core.root_path`); a step with ``root_alpha`` places it at

        root_start + a chord + a (1 - a) ((1 - a) root_deviation_start - a root_deviation_end)

    (``a = root_alpha``, ``chord = root_end - root_start``), where the deviations are
    ``T v - chord`` (m) for the root velocities ``v`` at the frame's start and end. Frames that
    share their end velocities give the root a continuous velocity (C1). Without velocities
    (:meth:`set_root_targets` or :meth:`bind_roots` called without them, the default) the
    deviations are zero and the root moves linearly, ``root_start + a chord``, exactly as before
    the path existed; ``frame_duration`` is then 0.
    """

    model: object
    root_start: wp.array
    root_end: wp.array
    #: per-frame data of the model's features (:class:`~dftl_warp.features.step.FeatureControl`:
    #: collider poses, mesh points, wind, bound-root mesh points); an :class:`AbsentFeatures` without
    #: features (whose calls say which feature they need)
    features: object = None
    #: per device strand, ``T v0 - (root_end - root_start)`` (m): the Hermite tangent's deviation
    #: from the chord at the frame's start; zeros (the default) for the linear path
    root_deviation_start: wp.array | None = None
    #: likewise at the frame's end, ``T v1 - (root_end - root_start)`` (m)
    root_deviation_end: wp.array | None = None
    #: the frame's duration ``T`` (s) the velocities were given for; 0 on the linear path
    frame_duration: float = 0.0
    #: (the last ``end`` passed to :meth:`set_root_targets`, its device-order copy)
    _last_end: tuple | None = field(default=None, init=False, repr=False)
    #: whether the deviations may be non-zero (so that going back to the linear path zeroes them)
    _bent: bool = field(default=False, init=False, repr=False)

    def __post_init__(self):
        if self.features is None:
            self.features = AbsentFeatures()
        for name in ("root_deviation_start", "root_deviation_end"):
            if getattr(self, name) is None:
                setattr(self, name, wp.zeros_like(self.root_start))
            else:
                self._bent = True

    @classmethod
    def at_rest(cls, model) -> Control:
        control = cls(model=model, root_start=wp.clone(model.root_rest), root_end=wp.clone(model.root_rest))
        if model.feature_data is not None:
            control.features = feature_hook("control")(model)
        return control

    @property
    def root_velocity_start(self) -> np.ndarray | None:
        """The roots' velocities at the frame's start (S, 3), input strand order, model units/s
        (``(deviation + chord) / T``); None on the linear path (no velocities were given)."""
        return self._velocities(self.root_deviation_start)

    @property
    def root_velocity_end(self) -> np.ndarray | None:
        """The roots' velocities at the frame's end (S, 3), input strand order, model units/s."""
        return self._velocities(self.root_deviation_end)

    def _velocities(self, deviation) -> np.ndarray | None:
        if self.frame_duration <= 0:
            return None
        chord = self.root_end.numpy().astype(np.float64) - self.root_start.numpy().astype(np.float64)
        device = (deviation.numpy().astype(np.float64) + chord) / self.frame_duration
        out = np.empty_like(device)
        out[self.model.layout.strand_order] = device
        return out

    def bind_roots(self, start, end=None, *, velocity_start=None, velocity_end=None,
                   frame_duration: float | None = None) -> None:
        """Set the frame's root targets from the world points (P, 3) of the model's root-binding
        mesh at frame start and end (``end`` defaults to ``start``): the features compute the
        bound roots (:meth:`~dftl_warp.features.step.FeatureControl.bound_roots`), the Control
        takes them. ``velocity_start``/``velocity_end`` (P, 3), the mesh points' velocities
        (units/s) at the frame's start and end, with ``frame_duration`` (s), give the roots the C1
        path (the bound roots' velocities are the same barycentric sums); without them the roots
        move linearly."""
        root_start, root_end = self.features.bound_roots(start, end)
        wp.copy(self.root_start, root_start)
        wp.copy(self.root_end, root_end)
        if velocity_start is None:
            self._linear(velocity_end, frame_duration)
            return
        duration = _check_duration(frame_duration)
        v0, v1 = self.features.binding.bound_velocities(velocity_start, velocity_end)
        from ..kernels.core.root_path import path_deviation_kernel

        m = self.model
        wp.launch(path_deviation_kernel(m.scalar), dim=m.num_strands, device=m.device,
                  inputs=[self.root_start, self.root_end, v0, v1, duration],
                  outputs=[self.root_deviation_start, self.root_deviation_end])
        self.frame_duration = duration
        self._bent = True

    def set_root_targets(self, start, end=None, *, velocity_start=None, velocity_end=None,
                         frame_duration: float | None = None) -> None:
        """Set the frame's root targets from world positions (S, 3) in input strand order.

        ``velocity_start`` and ``velocity_end`` (S, 3; ``end`` defaults to ``start``), the roots'
        velocities (units/s) at the frame's start and end, with ``frame_duration`` (s), make the
        root's path inside the frame the C1 Hermite curve (the class docstring); without them the
        roots move linearly from ``start`` to ``end``.

        A ``start`` equal to the previous call's ``end`` (frame after frame) reuses its conversion
        to device order. Equal in value, not the same object: an array moved in place between calls
        (``roots += step; set_root_targets(roots)``) kept the first call's targets, and the roots
        stood still without a word."""
        m = self.model
        end = start if end is None else end
        last = self._last_end
        device_start = last[1] if last is not None and _equal_rows(last[0], start) else m.roots_to_device(start)
        device_end = device_start if end is start else m.roots_to_device(end)
        self.root_start.assign(device_start)
        self.root_end.assign(device_end)
        self._last_end = (np.array(end, dtype=np.float64), device_end)   # a copy: the caller may move end
        if velocity_start is None:
            self._linear(velocity_end, frame_duration)
            return
        duration = _check_duration(frame_duration)
        velocity_end = velocity_start if velocity_end is None else velocity_end
        order = m.layout.strand_order
        chord = device_end.astype(np.float64) - device_start.astype(np.float64)
        dtype = device_start.dtype
        for name, v in (("root_deviation_start", velocity_start), ("root_deviation_end", velocity_end)):
            v = np.asarray(v, dtype=np.float64).reshape(-1, 3)
            if v.shape[0] != m.num_strands or not np.isfinite(v).all():
                raise ValueError(f"root velocities must be {m.num_strands} finite (3,) rows, one per strand")
            getattr(self, name).assign((duration * v[order] - chord).astype(dtype))
        self.frame_duration = duration
        self._bent = True

    def root_target_arrays(self, frame_duration: float) -> dict:
        """The device arrays :meth:`set_root_targets` fills (per device strand: ``start``, ``end``,
        ``deviation_start``, ``deviation_end``), for a caller that computes them on the device
        (the simulation's transform-driven roots: ``dftl_warp/simulation/transform_roots.py``); the
        path becomes the C1 one over ``frame_duration`` seconds."""
        self.frame_duration = _check_duration(frame_duration)
        self._bent = True
        self._last_end = None
        return {"start": self.root_start, "end": self.root_end, "deviation_start": self.root_deviation_start,
                "deviation_end": self.root_deviation_end}

    @property
    def root_path_curved(self) -> bool:
        """Whether the roots' path inside the frame has non-zero deviations from the linear one
        (root velocities were given); kernels may specialise on it (``wp.static``)."""
        return self._bent

    def _linear(self, velocity_end, frame_duration) -> None:
        """Back to the linear path (zero deviations)."""
        if velocity_end is not None or frame_duration is not None:
            raise ValueError("root velocities: give velocity_start (and velocity_end, frame_duration) together")
        if self._bent:
            self.root_deviation_start.zero_()
            self.root_deviation_end.zero_()
            self._bent = False
        self.frame_duration = 0.0


def _equal_rows(host: np.ndarray, rows) -> bool:
    """Whether ``rows`` holds exactly the values of ``host`` (a float64 copy), NaN never equal."""
    try:
        rows = np.asarray(rows, dtype=np.float64)
    except (TypeError, ValueError):
        return False
    return rows.shape == host.shape and bool(np.array_equal(rows, host))


def _check_duration(frame_duration) -> float:
    """``frame_duration`` as a float; ValueError unless it is a finite number of seconds > 0."""
    if frame_duration is None or not np.isfinite(frame_duration) or float(frame_duration) <= 0:
        raise ValueError(f"root velocities need frame_duration, a finite number of seconds > 0, got {frame_duration!r}")
    return float(frame_duration)
