"""Time-varying simulation data: :class:`State` (per particle) and :class:`Control` (per strand).

States are swapped between steps (``solver.step(state_in, state_out, ...)``); a step may also run
in place with ``state_in is state_out``.
"""

from __future__ import annotations

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
    step (``None`` when the solver does not carry it).

    When the model's layout interleaves its state vectors (:mod:`dftl_warp.core.layout`), the three
    arrays are views of one ``storage`` buffer, offset by 32 and 64 slots: each view's slots past
    a chunk's 32 entries belong to the other fields. Kernels index them through the layout and
    never notice; whole-array operations must go through the State (:meth:`assign`,
    :meth:`write`), never ``state.velocities.assign(...)`` or ``.zero_()`` on a view.
    """

    positions: wp.array
    velocities: wp.array
    corrections: wp.array | None
    #: the buffer the fields are views of (interleaved layouts), else None
    storage: wp.array | None = None

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
        )

    @classmethod
    def interleaved(cls, storage: wp.array, layout, with_corrections: bool) -> State:
        """The State whose fields are views of ``storage`` in the interleaved ``layout``."""
        fields = 3 if with_corrections else 2
        if layout.interleave < fields:
            raise ValueError(f"the layout interleaves {layout.interleave} state vectors; this State needs {fields}")
        return cls._views(storage, layout.num_slots, with_corrections)

    @classmethod
    def _views(cls, storage: wp.array, n: int, with_corrections: bool) -> State:
        """Fields as ``n``-slot views of ``storage``, 32 slots apart."""
        views = [storage[32 * f: 32 * f + n] for f in range(3 if with_corrections else 2)]
        return cls(positions=views[0], velocities=views[1], corrections=views[2] if with_corrections else None,
                   storage=storage)

    def clone(self) -> State:
        """A copy of this state in new device arrays."""
        if self.storage is not None:
            return State._views(wp.clone(self.storage), self.positions.shape[0], self.corrections is not None)
        return State(positions=wp.clone(self.positions), velocities=wp.clone(self.velocities),
                     corrections=None if self.corrections is None else wp.clone(self.corrections))

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
        a (num_slots, 3) array in the layout's slot order (``Model.points_to_device``), or to zero.

        Plain States assign the array; interleaved ones write only the field's own slots
        (``layout`` needed unless ``zero``), leaving the other fields untouched."""
        target = getattr(self, field)
        if target is None:
            raise ValueError(f"this State has no {field}")
        if self.storage is None:
            target.zero_() if zero else target.assign(values)
            return
        f = FIELDS.index(field)
        host = self.storage.numpy()
        if zero:
            # a field's own slots: every 32-slot run starting at a multiple of 32 F, offset 32 f
            n = host.shape[0]
            chunk = 32 * self._interleave()
            idx = np.arange(n)
            host[(idx % chunk) // 32 == f] = 0.0
        else:
            if layout is None:
                raise ValueError("writing an interleaved State needs its layout")
            slots = layout.slot_of_point
            host[slots + 32 * f] = np.asarray(values)[slots]
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


@dataclass(eq=False)
class Control:
    """Kinematic root targets per device strand, relative to ``model.origin`` (m).

    During a frame the root moves linearly from ``root_start`` to ``root_end``; a step with
    ``root_alpha`` places it at ``root_start + root_alpha (root_end - root_start)``.
    """

    model: object
    root_start: wp.array
    root_end: wp.array
    #: per-frame data of the model's features (:class:`~dftl_warp.features.step.FeatureControl`:
    #: collider poses, mesh points, wind, bound-root mesh points); None without features
    features: object = None
    #: (the last ``end`` passed to :meth:`set_root_targets`, its device-order copy)
    _last_end: tuple | None = field(default=None, init=False, repr=False)

    @classmethod
    def at_rest(cls, model) -> Control:
        control = cls(model=model, root_start=wp.clone(model.root_rest), root_end=wp.clone(model.root_rest))
        if model.feature_data is not None:
            control.features = feature_hook("control")(model)
        return control

    def bind_roots(self, start, end=None) -> None:
        """Set the frame's root targets from the world points (P, 3) of the model's root-binding
        mesh at frame start and end (``end`` defaults to ``start``): the features compute the
        bound roots (:meth:`~dftl_warp.features.step.FeatureControl.bound_roots`), the Control
        takes them."""
        if self.features is None:
            raise ValueError("the model has no RootBinding feature")
        root_start, root_end = self.features.bound_roots(start, end)
        wp.copy(self.root_start, root_start)
        wp.copy(self.root_end, root_end)

    def set_root_targets(self, start, end=None) -> None:
        """Set the frame's root targets from world positions (S, 3) in input strand order.

        Passing the previous call's ``end`` array as ``start`` (frame after frame, unchanged)
        reuses its conversion to device order."""
        m = self.model
        end = start if end is None else end
        last = self._last_end
        device_start = last[1] if last is not None and last[0] is start else m.roots_to_device(start)
        device_end = device_start if end is start else m.roots_to_device(end)
        self.root_start.assign(device_start)
        self.root_end.assign(device_end)
        self._last_end = (end, device_end)
