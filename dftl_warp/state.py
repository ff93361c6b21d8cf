"""Time-varying simulation data: :class:`State` (per particle) and :class:`Control` (per strand).

States are swapped between steps (``solver.step(state_in, state_out, ...)``); a step may also run
in place with ``state_in is state_out``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import warp as wp


@dataclass(eq=False)
class State:
    """Particle state in the model's layout, relative to ``model.origin``.

    positions: m; velocities: m/s; corrections: m, the prior form's carried ``x - p`` of the last
    step (``None`` when the solver does not carry it).
    """

    positions: wp.array
    velocities: wp.array
    corrections: wp.array | None

    @classmethod
    def at_rest(cls, model, *, with_corrections: bool = True) -> State:
        if model.rest_positions is None:
            raise ValueError("this model has no host rest positions (a synthetic groom built on the device); "
                             "copy an existing State with State.clone() instead")

        def zeros():
            return wp.zeros(model.num_points, dtype=model.vec3, device=model.device)

        return cls(
            positions=wp.array(model.rest_positions, dtype=model.vec3, device=model.device),
            velocities=zeros(),
            corrections=zeros() if with_corrections else None,
        )

    def clone(self) -> State:
        """A copy of this state in new device arrays."""
        return State(positions=wp.clone(self.positions), velocities=wp.clone(self.velocities),
                     corrections=None if self.corrections is None else wp.clone(self.corrections))

    def assign(self, other: State) -> None:
        """Copy ``other`` into this state (same model)."""
        wp.copy(self.positions, other.positions)
        wp.copy(self.velocities, other.velocities)
        if self.corrections is not None:
            if other.corrections is not None:
                wp.copy(self.corrections, other.corrections)
            else:
                self.corrections.zero_()

    def bytes_per_particle(self) -> int:
        arrays = [a for a in (self.positions, self.velocities, self.corrections) if a is not None]
        n = max(self.positions.shape[0], 1)
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
    #: per-frame data of the model's features (:class:`~dftl_warp.feature_data.FeatureControl`:
    #: collider poses, mesh points, wind, bound-root mesh points); None without features
    features: object = None

    @classmethod
    def at_rest(cls, model) -> Control:
        control = cls(model=model, root_start=wp.clone(model.root_rest), root_end=wp.clone(model.root_rest))
        if model.feature_data is not None:
            from .feature_data import FeatureControl

            control.features = FeatureControl(model, control)
        return control

    def set_root_targets(self, start, end=None) -> None:
        """Set the frame's root targets from world positions (S, 3) in input strand order."""
        m = self.model
        self.root_start.assign(m.roots_to_device(start))
        self.root_end.assign(m.roots_to_device(start if end is None else end))
