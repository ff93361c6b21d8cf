"""Energy-growth monitor: warn once, naming the setting, when a run creates energy.

Usage (one monitor per run, checked once per frame or as often as you like)::

    monitor = EnergyMonitor(solver, "dftl s=0.5 dt=1e-05 s")
    for frame in range(frames):
        solver.advance(state, control, dt, substeps)
        monitor.check(state, frame)
    if monitor.warned: ...   # monitor.message says what happened

``check`` issues one :class:`EnergyGrowthWarning` (a ``RuntimeWarning``, through :mod:`warnings`)
the first time the run's *available energy* (:mod:`dftl_warp.kernels.energy`: kinetic plus
potential energy above each strand's hanging rest state, per unit particle mass, J/kg) exceeds
its *budget*, or a position or velocity is not finite. Later checks stay silent.

The budget is what gravity and the roots can supply, with a safety factor:

    budget = factor * ( max(E_start, sum_s n_s |g| L_s, sum_s n_s (L_s / 1 s)^2 / 2) + sum_s 2 n_s u_s^2 )

with ``n_s`` the free particles of strand ``s``, ``L_s`` its length, ``E_start`` the available
energy at the first check and ``u_s`` the fastest root speed seen so far (a root moving at ``u``
can at most throw its strand at ``2 u``). With held roots a physical strand never exceeds
``max(E_start, ...)`` (``sum n |g| L`` is more than a strand standing straight up holds), so a run
above twice that has created energy: the signature of ``s < 1`` at small steps, where the
unbalanced corrections pump energy into the strand faster than follow-the-leader dissipates it.
DFTL with ``s = 1`` dissipates and never comes near the budget.

Cost: one small kernel launch and three per-strand arrays copied to the host per check.
"""

from __future__ import annotations

import warnings

import numpy as np
import warp as wp

from .kernels.energy import available_energy_kernel


class EnergyGrowthWarning(RuntimeWarning):
    """A run's energy grew beyond what gravity and the roots can supply: the setting is unstable."""


class EnergyMonitor:
    """Watches one run for energy growth; see the module docstring.

    Args:
        solver: any solver (``model`` and ``gravity`` attributes).
        setting: how the run was configured, named in the warning (e.g. ``"dftl s=0.5 dt=1e-5"``).
        factor: safety factor on the physical budget (default 2).
    """

    def __init__(self, solver, setting: str, *, factor: float = 2.0):
        self.solver = solver
        self.model = model = solver.model
        self.setting = setting
        self.factor = float(factor)
        self.warned = False
        self.message: str | None = None
        #: (frame, available energy J/kg, budget J/kg) of every check
        self.history: list[tuple[int | None, float, float]] = []
        gravity = np.array(solver.gravity, dtype=np.float64).reshape(3)
        self._gravity = wp.vec3d(*gravity)
        rest = model.rest_lengths.numpy().astype(np.float64)
        # per device strand: free particles and length
        base, stride, count = model.layout.strand_base, model.layout.strand_stride, model.layout.strand_count
        self._free = np.maximum(count - 1, 0).astype(np.float64)
        lengths = np.zeros(model.num_strands)
        for s in range(model.num_strands):
            if count[s] > 1:
                lengths[s] = rest[base[s] + stride[s] * np.arange(1, count[s])].sum()
        self._floor = max(
            float(np.sum(self._free * np.linalg.norm(gravity) * lengths)),
            float(np.sum(self._free * 0.5 * lengths**2)),
        )
        self._start: float | None = None
        self._root_speed = np.zeros(model.num_strands)
        n, dev = model.num_strands, model.device
        self._energy = wp.zeros(n, dtype=wp.float64, device=dev)
        self._speed = wp.zeros(n, dtype=wp.float64, device=dev)
        self._bad = wp.zeros(n, dtype=wp.int32, device=dev)

    def measure(self, state) -> tuple[float, float, bool]:
        """(available energy J/kg, budget J/kg, all finite) of ``state``; updates the root-speed
        record. Does not warn."""
        m = self.model
        if m.num_strands == 0:
            return 0.0, 0.0, True
        wp.launch(
            available_energy_kernel(m.scalar),
            dim=m.num_strands,
            inputs=[m.strand_base, m.strand_stride, m.strand_count, m.rest_lengths, self._gravity,
                    state.positions, state.velocities],
            outputs=[self._energy, self._speed, self._bad],
            device=m.device,
        )
        energy = float(self._energy.numpy().sum())
        speed = self._speed.numpy()
        finite = not bool(self._bad.numpy().any()) and np.isfinite(energy)
        if finite:
            np.maximum(self._root_speed, speed, out=self._root_speed)
            if self._start is None:
                self._start = energy
        start = self._start if self._start is not None else 0.0
        budget = self.factor * (max(start, self._floor) + float(np.sum(2.0 * self._free * self._root_speed**2)))
        return energy, budget, finite

    def check(self, state, frame: int | None = None) -> bool:
        """Measure ``state`` (at ``frame``); warn once if its energy exceeds the budget or it is
        not finite. Returns True when this run has been found unstable (now or earlier)."""
        energy, budget, finite = self.measure(state)
        self.history.append((frame, energy, budget))
        if self.warned:
            return True
        at = f" at frame {frame}" if frame is not None else ""
        if not finite:
            self.message = (f"{self.setting}: the simulation produced non-finite positions or velocities{at}; "
                            "this setting is unstable")
        elif energy > budget:
            self.message = (
                f"{self.setting}: energy grew to {energy:.3g} J/kg{at}, more than {budget:.3g} J/kg "
                f"({self.factor:g}x what gravity and the roots can supply); this setting is unstable "
                "(DFTL with damping s < 1 at small steps pumps energy in: use s = 1)"
            )
        else:
            return False
        self.warned = True
        warnings.warn(self.message, EnergyGrowthWarning, stacklevel=2)
        return True
