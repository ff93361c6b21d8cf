"""A simulation's saved state: what a resumed run (a batch job's checkpoint) continues from.

:func:`save_state` gives every group's State (the elastic solver's tensions, frames and clamp
ghosts too) and its energy check's records as numpy arrays; :func:`load_state` puts them back, and
the energy warning given before the save is given again, so a resumed run warns as the
uninterrupted one did.
"""

from __future__ import annotations

import numpy as np

from .multi_device import EXTRA_FIELDS


def save_state(sim) -> dict:
    """Everything needed to continue from the current frame, as numpy arrays (device layout). The
    energy check has checked the frame first (its records are those after the frame's check)."""
    sim.check_energy()
    state = {"frame": np.array(sim.frame)}
    for k, g in enumerate(sim.groups):
        for name in EXTRA_FIELDS:   # the elastic solver's State: tensions, frames, clamp ghosts
            if getattr(g.state, name, None) is not None:
                state[f"group{k}.{name}"] = getattr(g.state, name).numpy()
        if g.monitor is not None:   # the energy check's records and its warning, if given
            state.update({f"group{k}.monitor.{name}": v for name, v in g.monitor.save().items()})
        if getattr(g.state, "storage", None) is not None:  # interleaved: the fields share one buffer
            state[f"group{k}.storage"] = g.state.storage.numpy()
            continue
        state[f"group{k}.positions"] = g.state.positions.numpy()
        state[f"group{k}.velocities"] = g.state.velocities.numpy()
        if g.state.corrections is not None:
            state[f"group{k}.corrections"] = g.state.corrections.numpy()
    return state


def load_state(sim, state: dict) -> None:
    """Continue from a :func:`save_state` of the same scene and options."""
    import warp as wp

    for k, g in enumerate(sim.groups):
        for name in EXTRA_FIELDS:
            target = getattr(g.state, name, None)
            if target is None:
                continue
            key = f"group{k}.{name}"
            if key not in state or np.asarray(state[key]).shape[0] != target.shape[0]:
                raise ValueError(f"saved state has no {key} of {target.shape[0]} entries")
            target.assign(wp.array(np.asarray(state[key]), dtype=target.dtype, device=target.device))
        storage = getattr(g.state, "storage", None)
        if storage is not None:
            key = f"group{k}.storage"
            if key not in state or np.asarray(state[key]).shape[0] != storage.shape[0]:
                raise ValueError(f"saved state has no {key} of {storage.shape[0]} slots")
            storage.assign(wp.array(np.asarray(state[key]), dtype=g.model.vec3, device=g.model.device))
            continue
        for name in ("positions", "velocities", "corrections"):
            target = getattr(g.state, name)
            key = f"group{k}.{name}"
            if target is None:
                continue
            if key not in state:
                raise ValueError(f"saved state has no {key}")
            target.assign(wp.array(np.asarray(state[key]), dtype=g.model.vec3, device=g.model.device))
    sim.frame = int(state["frame"])
    sim._matrices = {}
    sim._at_rest = False
    # the saved frame was checked before the save: checked again now, it would read the colliders'
    # poses and mesh points of the Control's start, not of the frame, as the colliders' motion
    sim._checked = sim.frame
    _load_monitors(sim, state)
    if sim.guides is not None:
        sim.guides.reset()
    for g in sim.groups:
        if g.control.features is not None:
            g.control.features.resync()  # colliders start the next frame where it says


def _load_monitors(sim, state: dict) -> None:
    """The energy check continues from the saved records, its warning (given before the save)
    given again (the simulation's ``warnings``); a state saved without them (or without some: one
    saved before the check counted the colliders' motion) restarts the check."""
    for k, g in enumerate(sim.groups):
        if g.monitor is None:
            continue
        prefix = f"group{k}.monitor."
        saved = {name[len(prefix):]: v for name, v in state.items() if name.startswith(prefix)}
        if not saved or not set(g.monitor.save()) <= set(saved):
            g.monitor.restart(g.state)
            continue
        g.monitor.load(saved)
        if g.monitor.warned:
            sim.warn(g.monitor.message)
