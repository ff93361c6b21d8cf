"""A simulation group: prims simulated together, on one device or split over several.

:class:`Group` builds one Model, solver, State and Control per device from the group's strands
(``options.device``: one name, or a comma list such as ``cuda:0,cuda:1``, or ``cpu,cpu`` in
tests). On one device these are the plain objects. On several, the strands are cut into
contiguous runs of about equal particle count (:func:`~dftl_warp.simulation.multi_device.split_strands`)
and the parts are seen through the composites of :mod:`~dftl_warp.simulation.multi_device`, which
present the same interface; every part shares the group's world origin, so each strand is
computed exactly as on one device.
"""

from __future__ import annotations

import warnings
import numpy as np

from ..core.layout import strand_offsets
from ..core.model import Model, _world_origin
from ..errors import UserError
from ..features import HairHair, Wind, find, group_features, hair_hair_extent
from ..features.hair_hair import with_rest_density
from ..solvers import build_solver, carries_corrections
from ..usd.scene import transform_points
from .multi_device import (
    SplitControl,
    SplitModel,
    SplitMonitor,
    SplitSolver,
    SplitState,
    parse_devices,
    part_features,
    split_strands,
)
from .settings import check_extent, describe_setting
from .split_elastic import SplitElasticSolver, part_options


class Group:
    """Prims ``members`` of ``scene`` simulated together with ``settings``, from ``frame``.

    Attributes: ``model``, ``solver``, ``state``, ``control`` (plain on one device, composites
    over the parts on several), ``devices``, ``point_offsets`` (first point of each member prim,
    and the total), ``point_ranges`` (points of each part), ``dt`` (substep, s), ``monitor``.
    """

    def __init__(self, settings, members: list[int], scene, frame: int, options, input_strands=None):
        import warp as wp

        self.settings = settings
        self.members = members
        self.curves = curves = [scene.curves[i] for i in members]
        #: (path, strands, input strand of each or None) of the member prims, as messages name a strand
        #: (``input_strands``: prim index -> those of guides picked from a dense prim)
        self.prims = [(c.path, c.num_strands, (input_strands or {}).get(i)) for i, c in zip(members, curves)]
        self.input_strands = input_strands
        self.point_offsets = strand_offsets([c.num_points for c in curves], with_end=True)
        points = np.concatenate([transform_points(c.transform(frame), c.points) for c in curves])
        counts = np.concatenate([c.counts for c in curves])
        check_extent(points, self.point_offsets, curves, scene.source, options.precision)
        features, widths = group_features(scene, curves, frame)
        devices = parse_devices(options.device)
        ranges = split_strands(counts, len(devices)) if len(devices) > 1 else [(0, len(counts))]
        # a group of fewer strands than devices may fit in one part: it is then a plain one-device group
        # (on the first device), not composites over one part, which the clean start took for plain ones
        split = len(ranges) > 1
        starts = strand_offsets(counts, with_end=True)
        self.point_ranges = [(int(starts[s0]), int(starts[s1])) for s0, s1 in ranges]
        origin = grid_extent = None
        # the hair-hair grid's rest density from the group's points (a split group's parts all weigh
        # against the whole group's, and on one device or several alike)
        try:   # a grid of too many nodes is refused before the rest density allocates it
            features, _ = with_rest_density(features, points, counts, widths)
        except ValueError as exc:
            raise UserError(f"{scene.source}: {exc}") from None
        hair_hair = find(features, HairHair)
        if split:
            # every part shares the group's origin and (hair-hair) grid
            origin = _world_origin(points)
            grid_extent = None if hair_hair is None else hair_hair_extent(hair_hair, points, counts)
        extra = {} if options.iterations is None else {"iterations": options.iterations}
        elastic = settings.solver == "elastic"
        if settings.solver in ("rattle", "reference"):   # as the elastic solver, they need non-zero rest lengths
            from .elastic_setup import check_rest_lengths

            for c in curves:
                check_rest_lengths(scene.source, c, c.points, settings.solver)
        if elastic:
            from .elastic_setup import elastic_options

            extra, features = elastic_options(scene, curves, frame, features, widths, settings)
            extra["compute_precision"] = options.arithmetic
        models, solvers, states, controls = [], [], [], []
        for (s0, s1), (p0, p1), device in zip(ranges, self.point_ranges, devices):
            options_here = part_options(extra, p0, p1) if elastic and split else extra
            part = part_features(features, s0, s1, len(counts), scene.source, grid_extent) if split else features
            with wp.ScopedDevice(device):
                try:
                    model = Model.from_strands(
                        points[p0:p1], counts[s0:s1], device=device, precision=options.precision, origin=origin,
                        widths=None if widths is None else widths[p0:p1], features=part,
                        corrections=carries_corrections(settings.solver, settings.correction))
                except ValueError as exc:
                    raise UserError(f"{scene.source}: {exc}") from None
                try:
                    solver = build_solver(model, settings.solver, damping=settings.damping,
                                          correction=settings.correction, gravity=scene.gravity, **options_here)
                except ValueError as exc:
                    hint = (" (remove them from the scene or use --solver dftl)"
                            if elastic and "features" in str(exc) else "")
                    raise UserError(f"{scene.source}: {exc}{hint}") from None
                models.append(model)
                solvers.append(solver)
                states.append(solver.state())
                controls.append(model.control())
        self.devices = [str(m.device) for m in models]
        if split:
            self.model = SplitModel(models, ranges)
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always")
                self.solver = SplitElasticSolver(solvers, ranges) if elastic else SplitSolver(solvers)
            for w in caught:   # a splat interval a split groom cannot keep: one line naming file and prims
                note(scene, f"{scene.source}: {', '.join(c.path for c in curves)}: {w.message}", w.category)
            self.state = SplitState(states, models)
            self.control = SplitControl(controls, ranges)
        else:
            self.model, self.solver, self.state, self.control = models[0], solvers[0], states[0], controls[0]
        #: substep length, s
        self.dt = 1.0 / (scene.stage.time_codes_per_second * settings.substeps)
        self.monitor = None
        sources = energy_sources(features)
        if options.monitor and sources:
            # the monitor's account holds kinetic and gravitational energy only: a strand that
            # gains energy from these is not unstable, and it would say so (every hair-hair run did)
            note(scene, f"{scene.source}: {', '.join(c.path for c in curves)}: no energy check "
                        f"({' and '.join(sources)} {'add' if len(sources) > 1 else 'adds'} energy the check "
                        "cannot tell from an unstable setting)")
        elif options.monitor:
            from .monitor import EnergyMonitor

            setting = describe_setting(scene, members, settings, options)
            advice = None   # the default: DFTL with s < 1
            if not (settings.solver in ("dftl", "ftl") and settings.damping < 1.0):
                advice = "more substeps per frame (--substeps, or --quality production) may hold it"
            seconds = 1.0 / scene.stage.time_codes_per_second   # the time the controls' collider poses span
            monitors = [EnergyMonitor(s, setting, st, meters_per_unit=scene.stage.meters_per_unit, advice=advice,
                                      prims=self.prims, control=c, frame_duration=seconds)
                        for s, st, c in zip(solvers, states, controls)]
            self.monitor = SplitMonitor(monitors) if split else monitors[0]
        self._parts = list(zip(models, states))
        #: the elastic solver's clamp ghosts in each prim's local space (moved with the roots)
        self.clamps = None
        if elastic:
            from .elastic_setup import ClampDriver

            self.clamps = ClampDriver(self, frame)
        #: device buffers of local_samples per part, made on first use
        self._sample_buffers = None

    def restart_monitor(self) -> None:
        """The energy monitor (if any) takes the current state as the run's start."""
        if self.monitor is not None:
            self.monitor.restart(self.state)

    @property
    def num_strands(self) -> int:
        return self.model.num_strands

    @property
    def num_points(self) -> int:
        return int(self.point_offsets[-1])

    def local_samples(self, to_local: np.ndarray, rate: np.ndarray, owned: bool = True) -> tuple[np.ndarray, np.ndarray]:
        """Points and velocities (N, 3, float32) in input order and local space, from
        column-vector world-to-local matrices and frame rates per member prim
        (:class:`~dftl_warp.output.samples.LocalSamples`; ``owned=False``: views valid until the
        next call). Every part gathers and transforms its points on its device (all launched
        first); several parts are concatenated in input order (new arrays, the caller's)."""
        from ..output.samples import LocalSamples

        if self._sample_buffers is None:
            member = np.repeat(np.arange(len(self.members)), np.diff(self.point_offsets))
            self._sample_buffers = [LocalSamples(model, member[p0:p1])
                                    for (model, _), (p0, p1) in zip(self._parts, self.point_ranges)]
        for (model, state), buffers in zip(self._parts, self._sample_buffers):
            buffers.launch(model, state, to_local, rate)
        if len(self._sample_buffers) == 1:
            return self._sample_buffers[0].fetch(owned)
        gathered = [buffers.fetch(owned=False) for buffers in self._sample_buffers]
        return np.concatenate([p for p, _ in gathered]), np.concatenate([v for _, v in gathered])


def note(scene, message: str, category=UserWarning) -> None:
    """``message`` once among the scene's one-line notes (``scene.warnings``, printed with the run's
    other warnings), or as a Python warning where the scene keeps none."""
    notes = getattr(scene, "warnings", None)
    if notes is None:
        warnings.warn(message, category, stacklevel=3)
    elif message not in notes:
        notes.append(message)


def energy_sources(features) -> list[str]:
    """The features among ``features`` that can add energy to the hair beyond its roots' motion:
    wind, and hair-hair's repulsion (its compression energy is not in the energy monitor's
    account of kinetic and gravitational energy)."""
    sources = []
    if find(features, Wind) is not None:
        sources.append("the wind")
    hh = find(features, HairHair)
    if hh is not None and hh.repulsion > 0:
        sources.append("hair-hair's repulsion")
    return sources
