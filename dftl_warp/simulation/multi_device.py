"""One groom on several devices: ``dftl-warp simulate --device cuda:0,cuda:1,...``.

Strands of DFTL are independent of each other, so a simulation group's strands are cut into
contiguous runs of about equal particle count, one per device, each with its own
:class:`~dftl_warp.core.model.Model`, solver, :class:`~dftl_warp.core.state.State` and
:class:`~dftl_warp.core.state.Control`. Every part shares the world origin of the whole group, so each
strand is computed exactly as on one device: results are bitwise those of a single-device run on
the same kind of device. A frame launches every part before waiting for any (CUDA launches and
graph replays are asynchronous), so the devices work at the same time; the host gathers the parts
when the frame is written.

:class:`~dftl_warp.simulation.group.Group` builds the parts; the composites here
(:class:`SplitModel`, :class:`SplitSolver`, :class:`SplitState`, :class:`SplitControl`,
:class:`SplitMonitor`) present the single-device interface the frame loop uses. A device may
appear twice (``cpu,cpu``: two Models on one device, for tests).

Features (:mod:`dftl_warp.features`): colliders and wind are shared by every part; per-strand
values (drag rate, root-binding triangles) are sliced with the strands. Elastic strands have a
solver per part too (:mod:`~dftl_warp.simulation.split_elastic`).
Hair-hair interaction (:class:`~dftl_warp.features.HairHair`) couples strands through a grid:
every part gets the grid shape of the whole groom, and :class:`SplitSolver` then steps the parts
in lockstep, exchanging the grid each substep (:class:`GridExchange`): the lower corner is the
minimum of the parts' bounds and density and momentum are the sum of the parts' splats, both
combined on the first part's device and copied back to every part before it sweeps. The grid is
then the single-device one up to the order of the splat's sums (float rounding), and the results
agree with a single-device run to rounding, not bitwise. That path launches substep by substep
(no CUDA graph).
"""

from __future__ import annotations

import numpy as np

from ..core.devices import parse_devices  # noqa: F401  (re-exported)
from ..errors import UserError, plural
from ..features import Drag, HairHair, RootBinding


def split_strands(counts, parts: int) -> list[tuple[int, int]]:
    """Contiguous strand ranges ``[(s0, s1), ...]``, at most ``parts`` of them, none empty, with
    about equal numbers of particles (``counts`` are vertex counts per strand)."""
    counts = np.asarray(counts, dtype=np.int64)
    n = counts.shape[0]
    if n == 0:
        return [(0, 0)]
    ends = np.cumsum(counts)
    targets = ends[-1] * np.arange(1, parts) / parts
    cuts = np.searchsorted(ends, targets, side="left") + 1  # first strand of the next part
    bounds = sorted({0, n, *(int(c) for c in cuts if 0 < c < n)})
    return list(zip(bounds[:-1], bounds[1:]))


class SplitArray:
    """A per-particle field of the parts' States seen as one array: ``numpy()`` concatenates the
    parts' device arrays (each in its layout's slot order), ``assign`` writes them back through
    :meth:`State.write <dftl_warp.core.state.State.write>`, which leaves the other fields of an
    interleaved State untouched."""

    def __init__(self, states, models, name: str):
        self.states = list(states)
        self.models = list(models)
        self.name = name
        self.parts = [getattr(s, name) for s in self.states]

    def numpy(self) -> np.ndarray:
        return np.concatenate([p.numpy() for p in self.parts])

    def assign(self, values) -> None:
        import warp as wp

        host = values.numpy() if isinstance(values, wp.array) else np.asarray(values)
        start = 0
        for state, model, p in zip(self.states, self.models, self.parts):
            state.write(self.name, host[start:start + p.shape[0]])
            start += p.shape[0]
        if start != host.shape[0]:
            raise ValueError(f"expected {start} values, got {host.shape[0]}")

    @property
    def shape(self):
        return (sum(p.shape[0] for p in self.parts),)


class SplitField:
    """A plain array of each part's State (the elastic solver's tensions and frames per particle, its
    clamp ghosts per strand) seen as one: ``numpy()`` concatenates the parts' arrays, ``assign``
    cuts its values at the parts' lengths."""

    def __init__(self, arrays):
        self.parts = list(arrays)
        self.dtype = self.parts[0].dtype
        self.device = self.parts[0].device

    def numpy(self) -> np.ndarray:
        return np.concatenate([p.numpy() for p in self.parts])

    def assign(self, values) -> None:
        import warp as wp

        host = values.numpy() if isinstance(values, wp.array) else np.asarray(values)
        if host.shape[0] != self.shape[0]:
            raise ValueError(f"expected {self.shape[0]} values, got {host.shape[0]}")
        start = 0
        for p in self.parts:
            p.assign(host[start:start + p.shape[0]])
            start += p.shape[0]

    @property
    def shape(self):
        return (sum(p.shape[0] for p in self.parts),)


#: the elastic solver's State arrays beyond the base State's (:class:`SplitField` on several devices)
EXTRA_FIELDS = ("tensions", "frames", "clamps")


class SplitState:
    """The parts' States: ``positions``, ``velocities`` and ``corrections`` as :class:`SplitArray`;
    the elastic solver's ``tensions``, ``frames`` and ``clamps`` as :class:`SplitField` (None where
    the parts have none)."""

    def __init__(self, states, models):
        self.parts = list(states)
        models = list(models)
        self.positions = SplitArray(self.parts, models, "positions")
        self.velocities = SplitArray(self.parts, models, "velocities")
        has = [s.corrections is not None for s in self.parts]
        self.corrections = SplitArray(self.parts, models, "corrections") if all(has) else None
        for name in EXTRA_FIELDS:
            arrays = [getattr(s, name, None) for s in self.parts]
            setattr(self, name, SplitField(arrays) if all(a is not None for a in arrays) else None)


class SplitModel:
    """The parts' Models seen as one, in input strand and point order."""

    def __init__(self, models, strand_ranges):
        self.parts = list(models)
        self.strand_ranges = list(strand_ranges)
        first = self.parts[0]
        self.device = first.device
        self.precision = first.precision
        self.vec3 = first.vec3
        self.scalar = first.scalar
        self.origin = first.origin
        self.counts = np.concatenate([m.counts for m in self.parts])
        self.feature_flags = first.feature_flags

    @property
    def num_strands(self) -> int:
        return sum(m.num_strands for m in self.parts)

    @property
    def num_points(self) -> int:
        return sum(m.num_points for m in self.parts)


class _Broadcast:
    """The parts' feature controls seen as one: calls go to every part (their arguments are
    per-scene data: collider poses, mesh points, times); attributes are read from the first."""

    def __init__(self, parts):
        self._parts = list(parts)

    def __getattr__(self, name):
        values = [getattr(p, name) for p in self._parts]
        if callable(values[0]):
            return lambda *args, **kwargs: [v(*args, **kwargs) for v in values][0]
        return values[0]


class SplitControl:
    def __init__(self, controls, strand_ranges):
        self.parts = list(controls)
        self.strand_ranges = list(strand_ranges)
        has = [c.features is not None for c in self.parts]
        self.features = _Broadcast(c.features for c in self.parts) if all(has) else None

    def set_root_targets(self, start, end=None, *, velocity_start=None, velocity_end=None,
                         frame_duration=None) -> None:
        """Every part's root targets (and root velocities, for the C1 path), sliced by strands."""
        start = np.asarray(start)
        end = start if end is None else np.asarray(end)
        v0 = None if velocity_start is None else np.asarray(velocity_start)
        v1 = v0 if velocity_end is None else np.asarray(velocity_end)
        for c, (s0, s1) in zip(self.parts, self.strand_ranges):
            path = {} if v0 is None else {"velocity_start": v0[s0:s1], "velocity_end": v1[s0:s1],
                                          "frame_duration": frame_duration}
            c.set_root_targets(start[s0:s1], end[s0:s1], **path)

    def bind_roots(self, start, end=None, **path) -> None:
        """Every part's root targets from the root-binding mesh's world points (shared; and the
        points' velocities, for the C1 path: :meth:`~dftl_warp.core.state.Control.bind_roots`)."""
        for c in self.parts:
            c.bind_roots(start, end, **path)


def _copy(dest, src) -> None:
    """``wp.copy`` that first orders the copy after the work queued on ``src``'s device (Warp
    orders a peer copy after the destination's work and the source's later work after it)."""
    import warp as wp

    if dest.device != src.device and dest.device.is_cuda and src.device.is_cuda:
        dest.device.stream.wait_stream(src.device.stream)
    wp.copy(dest, src)


class GridExchange:
    """Makes the hair-hair grids of the parts' :class:`~dftl_warp.features.step.FeatureStep` objects
    the grid of the whole groom: each part's grid is combined into the first part's (through a
    scratch grid on its device), and the result copied back to every part."""

    def __init__(self, steps):
        import warp as wp

        from ..kernels.features.grid import grid_add_density_kernel, grid_add_kernel, grid_min_kernel

        self.steps = list(steps)
        first = self.steps[0]
        shapes = {tuple(s.model.feature_data.grid_shape) for s in self.steps}
        if len(shapes) != 1:
            raise ValueError(f"the parts' hair-hair grids differ in shape: {sorted(shapes)}")
        self.scratch = {name: wp.empty_like(a) for name, a in first.grid.items()}
        self._min = grid_min_kernel(first.model.scalar)
        self._add = grid_add_kernel(first.model.scalar)
        self._add_density = grid_add_density_kernel(first.model.scalar)
        #: the density the momentum was splatted with: "mass" where the grid keeps one (rebuilt every
        #: few substeps, its "density" splatted again every substep), else "density"
        self.mass = "mass" if first.grid["mass"].shape[0] else "density"

    def _combine(self, names, launch) -> None:
        first = self.steps[0]
        for step in self.steps[1:]:
            for name in names:
                _copy(self.scratch[name], step.grid[name])
            launch()
        for step in self.steps[1:]:
            for name in names:
                _copy(step.grid[name], first.grid[name])

    def combine_bounds(self) -> None:
        """Every part's ``lower`` <- the minimum over the parts (m)."""
        import warp as wp

        g, device = self.steps[0].grid, self.steps[0].model.device
        self._combine(("lower",), lambda: wp.launch(self._min, dim=3, device=device,
                                                    inputs=[self.scratch["lower"]], outputs=[g["lower"]]))

    def combine_splats(self) -> None:
        """Every part's momentum and the density splatted with it <- the sum over the parts."""
        import warp as wp

        g, device, mass = self.steps[0].grid, self.steps[0].model.device, self.mass
        self._combine((mass, "momentum"), lambda: wp.launch(
            self._add, dim=g[mass].shape, device=device,
            inputs=[self.scratch[mass], self.scratch["momentum"]], outputs=[g[mass], g["momentum"]]))

    def combine_density(self) -> None:
        """Every part's density (splatted alone, between rebuilds) <- the sum over the parts."""
        import warp as wp

        g, device = self.steps[0].grid, self.steps[0].model.device
        self._combine(("density",), lambda: wp.launch(
            self._add_density, dim=g["density"].shape, device=device,
            inputs=[self.scratch["density"]], outputs=[g["density"]]))


class SplitSolver:
    """Advances every part on its own device; all parts are launched before any is waited for.
    With hair-hair interaction the parts step in lockstep, exchanging their grid: the whole of it at
    each rebuild (every ``splat_interval`` substeps), the density alone in between."""

    def __init__(self, solvers):
        self.parts = list(solvers)
        self.gravity = self.parts[0].gravity
        steps = [getattr(s, "_features", None) for s in self.parts]
        self.exchange = None
        if all(step is not None and step.grid is not None for step in steps):
            self.exchange = GridExchange(steps)

    @property
    def carries_corrections(self) -> bool:
        return self.parts[0].carries_corrections

    def advance(self, state: SplitState, control: SplitControl, dt: float, substeps: int) -> None:
        import warp as wp

        if self.exchange is not None:
            self._advance_exchanging(state, control, dt, substeps)
            return
        for solver, s, c in zip(self.parts, state.parts, control.parts):
            with wp.ScopedDevice(solver.model.device):
                solver.advance(s, c, dt, substeps)

    def _advance_exchanging(self, state: SplitState, control: SplitControl, dt: float, substeps: int) -> None:
        """As ``DFTLSolver.advance`` substep by substep, every part's grid made the whole groom's
        (:class:`GridExchange`) between the bounds, splat and sweep phases: at a rebuild the bounds,
        then the momentum and its density; in every substep of a grid rebuilt every few, the density."""
        if sum(s.model.num_strands for s in self.parts) == 0:
            return
        parts = [(solver, solver._features, s, c) for solver, s, c in zip(self.parts, state.parts, control.parts)]
        real = np.dtype(self.parts[0].model.precision).type  # alpha rounded as on one device
        for k in range(substeps):
            alpha = float(real(k + 1) / real(substeps))
            due = [step.grid_due(alpha) for _, step, _, _ in parts]   # alike: the parts count the same substeps
            for _, step, s, c in parts:
                step.pose_and_bounds(s, c, alpha, grid=due[0])
            if due[0]:
                self.exchange.combine_bounds()
                for _, step, s, _ in parts:
                    step.splat(s, dt)
                self.exchange.combine_splats()
            if self.exchange.mass == "mass":
                for _, step, s, _ in parts:
                    step.splat_density(s)
                self.exchange.combine_density()
            for solver, _, s, c in parts:
                solver.step_on_grid(s, c, dt, alpha)


class SplitMonitor:
    """One energy monitor per part (dftl_warp.simulation.monitor), judged as one: a check measures
    every part, and its one warning names the worst strand of the whole group (input order) and
    counts the strands over budget in all parts, as one device's monitor does."""

    def __init__(self, monitors):
        self.parts = list(monitors)
        self.warned = False
        self.message = None

    def restart(self, state: SplitState) -> None:
        for monitor, s in zip(self.parts, state.parts):
            monitor.restart(s)

    def save(self) -> dict:
        """Every part's records (:meth:`EnergyMonitor.save <dftl_warp.simulation.monitor.EnergyMonitor.save>`)."""
        out = {f"part{j}.{k}": v for j, m in enumerate(self.parts) for k, v in m.save().items() if k != "message"}
        out["message"] = np.array(self.message or "")
        return out

    def load(self, saved: dict) -> None:
        for j, m in enumerate(self.parts):
            m.load({**{k.split(".", 1)[1]: v for k, v in saved.items() if k.startswith(f"part{j}.")},
                    "message": ""})
        self.message = str(saved["message"]) or None
        self.warned = self.message is not None

    def check(self, state: SplitState, frame=None) -> bool:
        import warnings

        from .monitor import EnergyGrowthWarning

        over = sum(float(monitor.measure(s)[2]) for monitor, s in zip(self.parts, state.parts))
        if self.warned:
            return True
        if over == 0:
            return False
        energy, budget, bad = (np.concatenate(v) for v in zip(*(m.verdicts() for m in self.parts)))
        pushed = np.concatenate([m.pushed() for m in self.parts])
        self.warned, self.message = True, self.parts[0].compose(energy, budget, bad, frame, pushed)
        warnings.warn(self.message, EnergyGrowthWarning, stacklevel=2)
        return True


def part_features(features, s0: int, s1: int, num_strands: int, where: str, grid_extent=None) -> list:
    """The features of strands ``s0:s1`` of a group: per-strand values sliced, scene-wide ones
    (colliders, wind) shared; hair-hair interaction gets ``grid_extent`` (3,), m, the whole
    group's grid size (:func:`~dftl_warp.features.hair_hair_extent`), so that every part's
    grid has the whole group's shape."""
    from dataclasses import replace

    def per_strand(values, what):
        v = np.asarray(values)
        if v.ndim == 0:
            return values
        if v.shape[0] != num_strands:
            raise UserError(f"{where}: {what} has {v.shape[0]} values for {plural(num_strands, 'strand')}; "
                            "cannot split it")
        return v[s0:s1]

    out = []
    for f in features:
        if isinstance(f, HairHair):
            if grid_extent is None:
                raise ValueError("part_features: a split hair-hair grid needs the whole group's grid_extent")
            f = replace(f, extent=np.asarray(grid_extent, dtype=np.float64).reshape(3))
        elif isinstance(f, RootBinding) and f.triangles is not None:
            f = replace(f, triangles=per_strand(f.triangles, "dftl:rootMesh triangles"),
                        weights=per_strand(f.weights, "dftl:rootMesh weights"))
        elif isinstance(f, Drag):
            f = replace(f, rate=per_strand(f.rate, "drag rate"))
        out.append(f)
    return out
