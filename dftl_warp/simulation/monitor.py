"""Energy-growth monitor: warn once, naming the setting, when a run creates energy.

Usage (one monitor per run, checked once per frame or as often as you like)::

    monitor = EnergyMonitor(solver, "dftl s=0.5 dt=1e-05 s", state)
    # with moving colliders: EnergyMonitor(solver, setting, state, control=control, frame_duration=T)
    for frame in range(frames):
        solver.advance(state, control, dt, substeps)
        monitor.check(state, frame)
    if monitor.warned: ...   # monitor.message says what happened

``check`` issues one :class:`EnergyGrowthWarning` (a ``RuntimeWarning``, through :mod:`warnings`)
the first time a strand's *available energy* (:mod:`dftl_warp.kernels.simulation.energy`: kinetic plus
potential energy above each strand's hanging rest state, per unit particle mass, J/kg) exceeds
its *budget*, or a position or velocity is not finite. Later checks stay silent. The model's
lengths are in stage units; the warning converts to J/kg with ``meters_per_unit``. The elastic
solver's strands (``solver.name == "elastic"``) also store energy in their bending and twist, which
a strand bent by a collider and let go turns into motion: their available energy is the solver's
total, kinetic, gravitational and elastic, above the elastic energy of the rest shape (inverse
statics' bending moments, which hold a styled strand up and which it cannot give away at rest), per
unit of the strand's mean particle mass (the kernel's docstring), read from the solver's rest data
and the State's frames and clamp ghosts.

Each strand is judged on its own (one unstable strand is not hidden in a large groom), against
the smaller of two budgets, each with a safety ``factor`` (default 2)::

    gross:  factor * ( E_start  +  floor  +  2 n (u_max + U_max)^2  [ +  P_lift ]  [ +  E_stored ] )
    held:   factor * ( E_moved  +  floor )

with ``n`` the strand's free particles, ``E_start`` its available energy in the initial state,
``u_max`` the fastest root speed seen so far (a root moving at ``u`` can at most throw its strand
at ``2 u``), ``U_max`` the fastest surface speed seen so far of a moving collider that could reach
the strand (a surface moving at ``U`` throws hair at up to about ``2 U``), ``P_lift = 2 |g| sum_i L_i``
the potential energy of the strand standing straight up from its root (``L_i``: particle ``i``'s rest
length from the root), counted once a moving collider has reached the strand (a collider, however
slow, can carry hair up: it does work by pushing, not only by striking), ``E_moved`` its energy at
the last check where its root had moved since the previous check, or a collider within its reach had
moved during the frame (``E_start`` if neither ever moved), and
``floor = floor_fraction * n * max(|g| L, (L/1 s)^2/2)`` (the energy scale of the strand, of length
``L``, falling its own length; 1e-4 of it by default), and, for an elastic strand, ``E_stored`` the
largest elastic energy (above its rest shape's) seen at a check where its root or a collider in reach
moved: the work they stored in its bending, which it may give back as motion once they stop.

Colliders are counted per strand (:mod:`~dftl_warp.simulation.monitor_colliders`): a collider is in a
strand's reach when a sphere holding it wherever it was during the frame comes within ``1.1 L`` (plus
the root's way since the last check) of the strand's root; a strand out of reach of every moving
collider keeps the budget of its root alone, and static colliders change no budget. The monitor
sees the colliders when it is given the run's Control and the frame's duration (``control``,
``frame_duration``) and is checked once a frame, after the frame (the Control then holds the poses
the colliders followed in it); without them a moving collider's work looks created.

A physical strand never gains energy while its root and the colliders it touches are held, and DFTL
with ``s = 1`` dissipates (the stability map in docs/accuracy.md records its largest energy / budget
ratio; on strands folded tighter than a right angle and moving fast since its pushes are scaled,
docs/accuracy/folded.md); a strand above its budget has *created* energy -- at least doubled it since its root (or a
collider in reach) last moved, or grown from rest to more than ``floor``. That is the signature of ``s < 1`` at small steps: the unbalanced
velocity corrections pump energy into the strand faster than follow-the-leader dissipates it,
and a strand hanging at rest starts to move by itself.

Pass the initial state to the constructor (or check it before the first frame): otherwise the
first check's state is taken as the start.

After a run, ``monitor.unstable`` (per device strand) and ``monitor.worst_ratio`` (largest
energy / budget seen) tell which strands blew up and by how much.

Cost: one small kernel launch per check (for elastic strands it also reads their frames), and four
totals copied to the host (a per-strand copy only when a strand first goes over its budget, to name it); with colliders, also the frame's poses (7
numbers per collider per pose) copied to the host and one launch per mesh collider over its points.
"""

from __future__ import annotations

import warnings

import numpy as np
import warp as wp

from ..core.layout import strand_offsets
from ..kernels.simulation.energy import elastic_terms_struct, energy_budget_kernel


class EnergyGrowthWarning(RuntimeWarning):
    """A run created energy beyond what it started with and its roots (and moving colliders) can supply,
    or its positions or velocities went non-finite: the setting is unstable."""


class EnergyMonitor:
    """Watches one run for energy growth; see the module docstring.

    Args:
        solver: any solver (``model`` and ``gravity`` attributes).
        setting: how the run was configured, named in the warning (e.g. ``"dftl s=0.5 dt=1e-5"``).
        state: the initial state (recommended), measured as the start of the run.
        factor: safety factor on the physical budget (default 2).
        floor_fraction: share of the strands' weight scale below which energy is never
            flagged (default 1e-4).
        control: the run's Control: its moving colliders' work is counted (module docstring);
            with ``frame_duration``, the seconds of one frame (the time the Control's poses span).
    """

    def __init__(self, solver, setting: str, state=None, *, factor: float = 2.0, floor_fraction: float = 1.0e-4,
                 meters_per_unit: float = 1.0, advice: str | None = None, prims=None, control=None,
                 frame_duration: float | None = None):
        self.solver = solver
        self.model = model = solver.model
        self.setting = setting
        self.factor = float(factor)
        #: the warning gives energies in J/kg: the model's lengths are stage units of this many m
        self.meters_per_unit = float(meters_per_unit)
        #: what the warning advises (default: the remedy for DFTL with damping s < 1)
        self.advice = advice or "DFTL with damping s < 1 at small steps pumps energy in: use s = 1"
        #: the prims whose strands the model holds, in order (features.clean_start.strand_name): the
        #: warning names a strand as its prim's, or the input's (None: a strand of the model)
        self.prims = prims
        self.warned = False
        self.message: str | None = None
        #: (frame, total available energy J/kg, total budget J/kg) of every check
        self.history: list[tuple[int | None, float, float]] = []
        gravity = np.array(solver.gravity, dtype=np.float64).reshape(3)
        self._gravity = wp.vec3d(*gravity)
        rest = model.rest_lengths.numpy().astype(np.float64)
        # per device strand: free particles and length
        base, stride, count = model.layout.strand_base, model.layout.strand_stride, model.layout.strand_count
        self._free = np.maximum(count - 1, 0).astype(np.float64)
        strand = np.repeat(np.arange(model.num_strands), count)
        first = strand_offsets(count)
        local = np.arange(strand.shape[0]) - np.repeat(first, count)
        along = rest[base[strand] + stride[strand] * local]
        lengths = np.bincount(strand, weights=along, minlength=model.num_strands)
        # each particle's rest length from its root (the roots' own is 0)
        from_root = np.cumsum(along)
        from_root -= np.repeat(from_root[first] - along[first], count)
        scale = np.maximum(np.linalg.norm(gravity) * lengths, 0.5 * lengths**2)
        self._floor = float(floor_fraction) * self._free * scale  # per device strand, J/kg
        n, dev = model.num_strands, model.device
        self._free_d = wp.array(self._free, dtype=wp.float64, device=dev)
        self._floor_d = wp.array(self._floor, dtype=wp.float64, device=dev)
        #: per device strand: how far from its root a collider can touch it (its length and 10 %)
        self._reach_d = wp.array(1.1 * lengths, dtype=wp.float64, device=dev)
        #: per device strand: the potential energy a collider can lift it to (J/kg, straight up from its root)
        lift = 2.0 * np.linalg.norm(gravity) * np.bincount(strand, weights=from_root, minlength=model.num_strands)
        self._lift_d = wp.array(lift, dtype=wp.float64, device=dev)
        #: the moving colliders (monitor_colliders.ColliderMotion), or None
        self.colliders = None
        if control is not None and getattr(control.features, "colliders", None) is not None:
            from .monitor_colliders import ColliderMotion

            if frame_duration is None:
                raise ValueError("EnergyMonitor: a control with colliders needs frame_duration (s)")
            self.colliders = ColliderMotion(control, frame_duration)
        self._no_colliders = wp.zeros(1, dtype=wp.float64, device=dev), wp.zeros(1, dtype=wp.vec3d, device=dev)
        # the records, per device strand, on the device (energy_budget_kernel): start energy, energy
        # when the root (or a collider in reach) last moved, root position, fastest root speed, largest
        # ratio, over budget once, fastest collider in reach, largest elastic energy when the root or a
        # collider in reach moved (elastic strands; 0 for chains)
        self._records = [wp.zeros(n, dtype=wp.float64, device=dev), wp.zeros(n, dtype=wp.float64, device=dev),
                         wp.zeros(n, dtype=wp.vec3d, device=dev), wp.zeros(n, dtype=wp.float64, device=dev),
                         wp.zeros(n, dtype=wp.float64, device=dev), wp.zeros(n, dtype=wp.int32, device=dev),
                         wp.zeros(n, dtype=wp.float64, device=dev), wp.zeros(n, dtype=wp.float64, device=dev)]
        self._out = [wp.zeros(n, dtype=wp.float64, device=dev), wp.zeros(n, dtype=wp.float64, device=dev),
                     wp.zeros(n, dtype=wp.int32, device=dev)]
        self._totals = wp.zeros(4, dtype=wp.float64, device=dev)
        self._first = True
        #: the elastic solver's energy terms (kernels/simulation/energy.py), or None for a chain's
        self._real, self._terms = self._elastic_terms(solver)
        if state is not None:
            self.measure(state)

    def _elastic_terms(self, solver):
        """(the computation precision, the energy terms struct) of an elastic solver's strands; for
        other solvers (float64, an empty struct: the kernel reads none of it)."""
        m = self.model
        if getattr(solver, "name", None) != "elastic":
            return wp.float64, elastic_terms_struct(m.scalar, wp.float64)()
        terms = elastic_terms_struct(m.scalar, solver.real)()
        # the solver's rest data (overwritten in place by adopt_rest_shape, so read at every check)
        for name, array in solver.energy_arrays().items():
            setattr(terms, name, array)
        # the rest shape's bending and twist energy: the measure starts from it
        terms.rest_energy = wp.array(solver.rest_energy_per_mass(), dtype=wp.float64, device=m.device)
        return solver.real, terms

    @property
    def elastic(self) -> bool:
        """Whether the strands' energy counts their bending and twist (the elastic solver's)."""
        return self._terms.mass is not None

    @property
    def unstable(self) -> np.ndarray:
        """Per device strand: True once its energy has exceeded its budget."""
        return self._records[5].numpy().astype(bool)

    @property
    def worst_ratio(self) -> np.ndarray:
        """Per device strand: largest ratio of available energy to budget seen so far."""
        return self._records[4].numpy()

    @property
    def collider_speed(self) -> np.ndarray:
        """Per device strand: the fastest surface speed (model units/s) of a moving collider seen within
        its reach so far (0 without one)."""
        return self._records[6].numpy()

    @property
    def stored_energy(self) -> np.ndarray:
        """Per device strand: the largest elastic energy (above its rest shape's, J/kg in model units)
        seen at a check where its root or a collider in its reach moved (0 for chains)."""
        return self._records[7].numpy()

    def restart(self, state) -> None:
        """Take ``state`` as the start of the run (e.g. after a clean start moved hair out of a
        collider, or a preroll: energy they add or remove is not the run's)."""
        for record in self._records[3:]:
            record.zero_()
        if self.elastic:   # the rest shape may have changed (the clean start adopts the pushed-out shape)
            self._terms.rest_energy.assign(self.solver.rest_energy_per_mass())
        self._first = True
        self.measure(state)

    def save(self) -> dict:
        """The records a resumed run continues from (numpy arrays; :meth:`load`): each strand's
        budget records, whether the next check is the first, the warning given (empty: none), and the
        mesh colliders' points at the last check."""
        records = self._records if self.elastic else self._records[:7]   # a chain stores no elastic energy
        out = {f"record{i}": r.numpy() for i, r in enumerate(records)}
        if self.colliders is not None:
            out.update(self.colliders.save())
        out["first"] = np.array(self._first)
        out["message"] = np.array(self.message or "")
        return out

    def load(self, saved: dict) -> None:
        """Continue from :meth:`save`'s records (of a monitor of the same strands)."""
        if self.elastic and "record7" not in saved:
            raise ValueError("saved energy records do not count the elastic energy")
        for i, r in enumerate(self._records if self.elastic else self._records[:7]):
            values = np.asarray(saved[f"record{i}"])
            if values.shape[0] != r.shape[0]:
                raise ValueError(f"saved energy records have {values.shape[0]} strands, not {r.shape[0]}")
            r.assign(wp.array(values, dtype=r.dtype, device=r.device))
        if self.colliders is not None:
            self.colliders.load(saved)
        self._first = bool(saved["first"])
        self.message = str(saved["message"]) or None
        self.warned = self.message is not None

    def measure(self, state) -> np.ndarray:
        """Update the per-strand records and verdicts with ``state`` on the device (no warning);
        returns the totals (available energy of the finite strands J/kg, budget J/kg, strands over
        budget, strands not finite), which waits for the device."""
        m = self.model
        if m.num_strands == 0:
            return np.zeros(4)
        self._totals.zero_()
        if self.colliders is not None:
            self.colliders.update(bool(self._first))
            c = self.colliders
            colliders = [c.center, c.reach, c.speed, c.count]
        else:
            none, center = self._no_colliders
            colliders = [center, none, none, 0]
        terms = self._terms
        if self.elastic:
            if getattr(state, "frames", None) is None:
                raise ValueError("the energy check of elastic strands needs the elastic solver's States")
            terms.frames, terms.clamps = state.frames, state.clamps
        wp.launch(
            energy_budget_kernel(m.scalar, self._real, self.elastic),
            dim=m.num_strands,
            inputs=[m.strand_base, m.strand_stride, m.strand_count, m.rest_lengths, self._gravity, self.factor,
                    self._free_d, self._floor_d, state.positions, state.velocities, terms, int(self._first),
                    self._reach_d, self._lift_d, *colliders, *self._records],
            outputs=[*self._out, self._totals],
            device=m.device,
        )
        self._first = False
        return self._totals.numpy()

    def check(self, state, frame: int | None = None) -> bool:
        """Measure ``state`` (at ``frame``); warn once if any strand's energy exceeds its budget
        or is not finite. Returns True when this run has been found unstable (now or earlier)."""
        totals = self.measure(state)
        self.history.append((frame, float(totals[0]), float(totals[1])))
        if self.warned:
            return True
        if totals[2] == 0:
            return False
        self.message = self.compose(*self.verdicts(), frame)
        self.warned = True
        warnings.warn(self.message, EnergyGrowthWarning, stacklevel=2)
        return True

    def verdicts(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The last measure's available energy, budget (model units) and not-finite flag of every
        strand, in input strand order."""
        out = [self._input_order(a.numpy()) for a in self._out]
        return out[0], out[1], out[2].astype(bool)

    def pushed(self) -> np.ndarray:
        """Per strand, in input order: whether a moving collider has reached it (its budget counts
        that collider's work: :attr:`collider_speed` > 0)."""
        return self._input_order(self.collider_speed) > 0.0

    def _input_order(self, values: np.ndarray) -> np.ndarray:
        inputs = np.empty_like(values)
        inputs[self.model.layout.strand_order] = values
        return inputs

    def compose(self, energy, budget, bad, frame=None, pushed=None) -> str:
        """The warning for the verdicts (input strand order; strands of several monitors
        concatenated, with their :meth:`pushed` in ``pushed``; default this monitor's) of a check at
        ``frame``: the worst strand named as its prim's (:attr:`prims`), its budget as what its root,
        and moving colliders where one reached it, can supply."""
        over = bad | (energy > budget)
        at = f" at frame {frame}" if frame is not None else ""
        with np.errstate(divide="ignore", invalid="ignore"):
            ratio = energy / budget
        k = int(np.argmax(np.where(bad, np.inf, ratio)))
        count = int(over.sum())
        which = f"{self._name(k)}" + (f" (and {count - 1} more)" if count > 1 else "")
        if bad.any():
            return f"{self.setting}: {which}: non-finite positions or velocities{at}; this setting is unstable"
        joules = self.meters_per_unit**2  # (stage units / s)^2 -> J/kg
        supply = "its root and moving colliders" if (self.pushed() if pushed is None else pushed)[k] else "its root"
        return (f"{self.setting}: {which}: energy grew to {energy[k] * joules:.3g} J/kg{at}, more than "
                f"{budget[k] * joules:.3g} J/kg ({self.factor:g}x what it started with and {supply} can supply); "
                f"this setting is unstable ({self.advice})")

    def _name(self, strand: int) -> str:
        if not self.prims:
            return f"strand {strand}"
        from ..features.clean_start import strand_name

        return strand_name(self.prims, strand, path=False)
