"""Host orchestration: Scene -> Model/Solver/Control per settings group -> frame loop -> writer.

- :func:`simulate_usd` is the one-call API behind ``dftl-warp simulate``.
- :class:`Simulation` steps a scene frame by frame and can export / import its complete state
  (:meth:`Simulation.save_state`, :meth:`Simulation.load_state`), so that a batch or resume
  feature can start at any frame and continue a partial output with
  :meth:`~dftl_warp.output.base.FrameWriter.reopen`.

Simulation happens in world space, in stage units. Each frame is ``substeps`` solver steps of
``dt = 1 / (timeCodesPerSecond * substeps)`` seconds; roots move from where the prim's (possibly
animated) local-to-world transform puts them at the frame's start to where it puts them at its
end, on the Control's C1 root path (:class:`~dftl_warp.core.state.Control`, :mod:`.root_paths`):
a cubic Hermite curve whose end velocities are the roots' fourth-order differences over the
neighbouring frames (:func:`~dftl_warp.core.state.frame_velocity`; one-sided at the shot's ends,
the first frame and :attr:`Simulation.last_frame`), so a root's velocity does not jump at frames.
Roots bound to a mesh, the elastic solver's clamp ghosts and animated collider poses take the same
path (a deforming collider mesh moves linearly between frames: a start note says so).
Results go back to each prim's local space: points through the inverse transform; velocities are the motion *relative to the prim's frame* expressed
in local space, ``(v_world - v_frame(x)) @ inverse(linear part)`` with ``v_frame`` the velocity
the transform's own path (the roots') gave a point fixed in the prim over the last substep. That
is what USD's ``velocities`` mean (the derivative of the local ``points``): renderers add the
transform's own motion blur on top. For a static transform it is just the linear part's inverse.
The first frame is the input at rest: zero velocities.
"""

from __future__ import annotations

import numbers
import sys
import time
import warnings
from dataclasses import asdict, replace

import numpy as np

from ..core.devices import DeviceNotFound, lookup_device, parse_devices, resolve_device
from ..errors import UserError, WarningRoute, check_path, once, plural
from .monitor import EnergyGrowthWarning
from ..usd.scene import Scene, transform_points
from . import root_paths, saved_state, transform_roots
from .elastic_setup import note_unstable
from .group import Group
from .summary import Summary  # noqa: F401  (re-exported: what simulate_usd returns)
from .settings import unused_prim_settings, unused_solver_options
from .settings import (  # noqa: F401  (re-exported: the simulation's settings)
    DEFAULT_CORRECTION,
    DEFAULT_DAMPING,
    DEFAULT_SOLVER,
    DEFAULT_SUBSTEPS,
    MAX_EXTENT,
    GroupSettings,
    SimulationOptions,
    check_extent,
    describe_setting,
    group_settings,
    frame_range_note,
    last_written_frame,
    resolve_frames,
)


class Simulation:
    """A scene being simulated, one frame at a time, starting at ``frame``.

    ``samples()`` gives the current frame's points and velocities per prim in local space;
    ``advance()`` steps to the next frame.
    """

    def __init__(self, scene: Scene, options: SimulationOptions, frame: int, tolerance: float | None = None,
                 guides: dict | None = None, device_option: str = "--device", resuming: bool = False):
        import warp as wp

        # None or a dict failed later with an AttributeError that named neither
        if not isinstance(scene, Scene):
            raise TypeError(f"scene must be a dftl_warp Scene (read_scene), got {type(scene).__name__}")
        if not isinstance(options, SimulationOptions):
            raise TypeError(f"options must be a dftl_warp SimulationOptions, got {type(options).__name__}")
        # a frame of 1.5 was truncated to 1, "1" taken as 1; a tolerance of -1 or NaN accepted
        if isinstance(frame, (bool, np.bool_)) or not isinstance(frame, numbers.Real) or not float(frame).is_integer():
            raise ValueError(f"frame must be a whole frame number, got {frame!r}")
        from ..options import check_api

        tolerance = check_api("tolerance", tolerance)
        #: what is written (:meth:`samples` gives one pair per prim of it); ``scene`` is what is simulated
        self.output_scene = scene
        #: guides and render curves (issue 22, :mod:`dftl_warp.guides.scene`): render prims (``rel
        #: dftl:guides``, or ``guides={"guides": N}``) are deformed from simulated guides, not simulated
        self.guides = None
        if guides is not None and guides.get("guides") is None:
            guides = None if not any(c.guides for c in scene.curves) else guides
        if guides is not None or any(c.guides for c in scene.curves):
            from ..guides.scene import GuideSet

            self.guides = GuideSet(scene, int(frame), **(guides or {}))
            scene = self.guides.sim_scene
            self.output_scene = self.guides.output_scene
        self.scene = scene
        self.options = options
        self.frame = int(frame)
        #: the shot: its first frame (this one; a resumed run is made at it too, with ``resuming``,
        #: then loads its state: :meth:`load_state`) and its last (set by :func:`run_frames`; None: unknown). The roots' velocities
        #: are one-sided there (:meth:`advance`)
        self.first_frame = int(frame)
        self.last_frame: int | None = None
        devices = []
        for name in parse_devices(resolve_device(options.device)):  # a list splits the strands (multi_device)
            try:
                devices.append(lookup_device(name))
            except DeviceNotFound as exc:   # named as the user gave it: --device (command line), device (job file, API)
                raise UserError(f"{device_option} {name}: {exc}") from None
        self.device = devices[0]
        options = replace(options, device=",".join(str(d) for d in devices))
        self.options = options
        # prims are grouped by solver settings and by the mesh their roots are bound to, if any
        by_settings: dict[tuple, list[int]] = {}
        for i, c in enumerate(scene.curves):
            settings = group_settings(scene, options, i)
            scene.warnings.extend(unused_prim_settings(scene, i, settings, options))
            key = (settings, c.root_mesh.path if c.root_mesh is not None else None,
                   c.material.path if settings.solver == "elastic" and c.material is not None else None)
            by_settings.setdefault(key, []).append(i)
        # one Group per key, on one device or split over the list (simulation.group)
        picked = {} if self.guides is None else self.guides.input_strands
        self.groups = [Group(key[0], m, scene, self.frame, options, picked) for key, m in by_settings.items()]
        self._roots_local = [c.points[c.root_indices] for c in scene.curves]
        #: group index -> (frame, world root targets at that frame): the last advance's end targets
        self._end_roots: dict = {}
        #: group index -> its device root paths (simulation.transform_roots)
        self.transform_roots: dict = {}
        #: (what, group index, frame) -> world roots or clamp ghosts at that frame (root_paths)
        self._at_frame: dict = {}
        #: group index -> substeps of its last advance (the frame's velocity over the last substep)
        self._last_substeps: dict = {}
        self._matrices = {}
        #: True until the first advance: the state is the input at rest (zero velocities)
        self._at_rest = True
        #: one-line warnings raised while stepping (energy growth), in order
        self.warnings: list[str] = []
        #: called with each new warning as it happens (e.g. to print it above a progress bar)
        self.on_warning = None
        #: the last frame whose energy was checked
        self._checked = None
        #: prims already warned about turning faster than their root path follows (root_paths)
        self.fast_turns: set[str] = set()
        #: one-line notes of the set-up (Summary.start_notes says which), printed with the device
        #: line and kept in Summary.warnings and a batch checkpoint (a resumed run repeats them)
        self.start_notes: list[str] = self._clean_start(preroll=not resuming)
        for g in self.groups:   # energy budgets, and styles that cannot stand, from what the clean start left
            g.restart_monitor()
            if g.settings.solver == "elastic":
                note_unstable(scene, g)
        note = root_paths.collider_note(scene)   # deforming collider meshes change once a frame
        if note is not None:
            self.start_notes.append(note)
        #: ``--tolerance``: substeps (and solvers) chosen per frame (simulation.tolerance), else None
        self.tolerance = None
        if tolerance is not None:
            from .tolerance import setup

            self.tolerance = setup(self, tolerance)

    def _clean_start(self, preroll: bool = True) -> list[str]:
        """Hair that starts inside a collider is moved out, and ``options.preroll`` seconds settle
        the groom, with roots and colliders held at the first frame's pose
        (:mod:`dftl_warp.features.clean_start`). A group split across devices
        is moved out and settled as one. ``preroll=False`` (a run that resumes from a saved state,
        which replaces the settled one): the hair is moved out, so that elastic strands rest where
        they were moved as in the run that saved it (the saved state does not hold the rest
        shape), but the preroll is not stepped."""
        import warp as wp

        from ..features import update_frame
        from ..features.clean_start import inside_note, resolve_parts
        from ..features.clean_start import preroll as settle
        from .elastic_setup import rest_where_moved

        notes = []
        seconds = float(self.options.preroll or 0.0) if preroll else 0.0
        mpu = self.scene.stage.meters_per_unit
        units = {1.0: "m", 0.01: "cm", 0.001: "mm"}.get(mpu, "stage units")
        for k, g in enumerate(self.groups):
            has_colliders = g.control.features is not None and g.control.features.colliders is not None
            if not has_colliders and seconds <= 0:
                continue
            split = len(g.devices) > 1
            mine = []
            with wp.ScopedDevice(self.device):
                roots = self._roots_world(g, self.frame)
                g.control.set_root_targets(roots, roots)
                update_frame(self.scene, g.curves, g.control, self.frame, self.frame)  # the first frame's pose
                if has_colliders:
                    # per strand, so a split group is pushed out part by part exactly as on one device
                    parts = list(zip(g._parts, g.control.parts)) if split else [((g.model, g.state), g.control)]
                    # the groom's report decides whether and how long to push out, as on one device
                    report = resolve_parts([(m, st, c) for (m, st), c in parts], inside_only=True)
                    if report.inside:   # a clean scene says nothing
                        mine.append(report.line(units))
                        if g.settings.solver == "elastic":   # elastic strands rest where they were moved
                            mine += rest_where_moved(g, self.frame)
                if seconds > 0:
                    tcps = self.scene.stage.time_codes_per_second
                    mine.append(settle(g.solver, g.state, g.control, seconds, 1.0 / tcps, g.settings.substeps,
                                       resolve=has_colliders).line(units))
                # several groups: each line names its prims after its tag ('preroll: /A, /B: ...')
                whose = ", ".join(c.path for c in g.curves) if len(self.groups) > 1 else None
                notes += [line if whose is None else line.replace(": ", f": {whose}: ", 1) for line in mine]
                if has_colliders:   # what the push-out (and the preroll) could not free, in one line
                    notes += filter(None, [inside_note(parts, g.prims, units)])
                if g.control.features is not None:
                    g.control.features.resync()
        return notes

    # -- geometry helpers ---------------------------------------------------------------------

    def _matrix(self, index: int, frame: int) -> np.ndarray:
        key = (index, frame)
        m = self._matrices.get(key)
        if m is None:
            m = self._matrices[key] = self.scene.curves[index].transform(frame)
        return m

    def _forget_before(self, frame: int) -> None:
        self._matrices = {k: v for k, v in self._matrices.items() if k[1] >= frame}
        self._at_frame = {k: v for k, v in self._at_frame.items() if k[2] >= frame}

    def _roots_world(self, group: Group, frame: int) -> np.ndarray:
        return np.concatenate([
            transform_points(self._matrix(i, frame), self._roots_local[i]) for i in group.members
        ])

    # -- stepping -----------------------------------------------------------------------------

    @property
    def num_strands(self) -> int:
        return sum(g.num_strands for g in self.groups)

    @property
    def num_points(self) -> int:
        return sum(g.num_points for g in self.groups)

    def check_energy(self) -> None:
        """Run each group's energy monitor on the current frame (once per frame); a new warning
        goes to :attr:`warnings` and :attr:`on_warning`. It reads results back, so it waits for
        the device: :meth:`samples` calls it, after the frame's results are needed anyway."""
        if self._checked == self.frame or self._at_rest:
            return
        self._checked = self.frame
        for g in self.groups:
            if g.monitor is None or g.monitor.warned:
                continue
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", EnergyGrowthWarning)
                if g.monitor.check(g.state, self.frame):
                    self.warn(g.monitor.message)

    def warn(self, message: str) -> None:
        """A warning found while running: kept in :attr:`warnings` and passed to :attr:`on_warning`, once."""
        if message in self.warnings:
            return
        self.warnings.append(message)
        if self.on_warning is not None:
            self.on_warning(message)

    def samples(self, owned: bool = True) -> list[tuple[np.ndarray, np.ndarray]]:
        """(points, velocities) of every prim of :attr:`output_scene` at the current frame, local
        space, float32: :meth:`simulated_samples`, plus render curves deformed from their guides."""
        if self.guides is None:
            return self.simulated_samples(owned)
        return self.guides.samples(self, self.simulated_samples(True), self.device)

    def simulated_samples(self, owned: bool = True) -> list[tuple[np.ndarray, np.ndarray]]:
        """(points, velocities) of every prim of ``scene.curves`` at the current frame, in the
        prim's local space (stage units, stage units per second), float32 as USD stores them.

        The gather into input order and the transforms run on the simulation device
        (:mod:`dftl_warp.kernels.output.samples`); the host receives one copy per group. With
        ``owned=False`` the arrays are views of the host buffers, valid until the next call
        (no host copy: :func:`run_frames` writes them before it fetches again)."""
        self.check_energy()
        out: list = [None] * len(self.scene.curves)
        for index, g in enumerate(self.groups):
            to_local = np.empty((len(g.members), 4, 4))
            rate = np.zeros((len(g.members), 4, 4))
            substeps = self._last_substeps.get(index, g.settings.substeps)
            for k, i in enumerate(g.members):
                to_local[k] = np.linalg.inv(self._matrix(i, self.frame)).T
                if self.scene.curves[i].animated and not self._at_rest:
                    rate[k] = root_paths.matrix_rate(self, i, self.frame, substeps).T
            points, velocities = g.local_samples(to_local, rate, owned)
            for k, i in enumerate(g.members):
                a, b = g.point_offsets[k], g.point_offsets[k + 1]
                out[i] = (points[a:b], velocities[a:b])
        return out

    def advance(self) -> None:
        """Simulate from the current frame to the next one. On a GPU this only launches the work
        (it returns before the device is done); :meth:`samples` waits for it."""
        import warp as wp

        from ..features import update_frame

        self.check_energy()  # the frame being left, if nobody looked at it
        nxt = self.frame + 1
        with wp.ScopedDevice(self.device):
            shot = root_paths.shot(self)
            for k, g in enumerate(self.groups):
                animated = any(self.scene.curves[i].animated for i in g.members)
                if animated and transform_roots.drive(self, k, g, self.frame, nxt):
                    root_paths.warn_fast_turns(self, g, self.frame, nxt)
                elif animated:
                    # the C1 path from the roots at this frame, the next and their neighbours, each
                    # computed once (this frame's are the last frame's end targets, the same array,
                    # so the Control reuses their device-order copy too)
                    path = root_paths.frame_path(self, "roots", k, g, self.frame, nxt)
                    root_paths.warn_fast_turns(self, g, self.frame, nxt)
                    start, end = path["start"], path["end"]
                    self._end_roots[k] = (nxt, end)
                    g.control.set_root_targets(**path)
                    if g.clamps is not None:   # the elastic clamp turns with the roots' transforms
                        g.solver.set_clamp_targets(**root_paths.frame_path(self, "clamps", k, g, self.frame, nxt))
                # colliders, wind, bound roots (the latter on the C1 path too)
                update_frame(self.scene, g.curves, g.control, self.frame, nxt, shot=shot)
                root_paths.bound_clamps(g)   # roots bound to an animated mesh: the clamp turns with it
                substeps, dt = g.settings.substeps, g.dt
                if self.tolerance is not None:   # --tolerance: from the error estimate on sampled strands
                    frame_dt = 1.0 / self.scene.stage.time_codes_per_second
                    roots = self._end_roots[k] if k in self._end_roots and self._end_roots[k][0] == nxt else None
                    substeps = self.tolerance.substeps(k, g, frame_dt, None if roots is None else (start, end),
                                                       self.frame, nxt)
                    dt = frame_dt / substeps
                g.solver.advance(g.state, g.control, dt, substeps)
                self._last_substeps[k] = substeps
        self.frame = nxt
        self._at_rest = False
        self._forget_before(nxt - 3)   # the root path's differences reach 3 frames back (root_paths)

    # -- state for batch / resume ----------------------------------------------------------------

    def save_state(self) -> dict:
        """Everything needed to continue from the current frame, as numpy arrays (device layout;
        :func:`~dftl_warp.simulation.saved_state.save_state`)."""
        return saved_state.save_state(self)

    def load_state(self, state: dict) -> None:
        """Continue from a :meth:`save_state` of the same scene and options (made with
        ``resuming=True`` it skips the preroll, whose result the saved state replaces)."""
        saved_state.load_state(self, state)


def run_frames(sim: Simulation, writer, last_frame: int, *, progress=None, write_first: bool = True,
               frame_step: int = 1, first_frame: int | None = None, qc=None, gates=None,
               velocities: bool = True) -> dict:
    """Write the current frame (if ``write_first``), then advance and write up to ``last_frame``.

    Simulating and writing overlap: the next frame's substeps are launched before the current
    frame is authored, so on a GPU (where launches return at once) the device simulates frame
    ``f + 1`` while the host writes frame ``f``; :meth:`Simulation.samples` then waits for it.
    On the CPU device the two simply alternate.

    Every frame is simulated; only frames ``first_frame + k * frame_step`` are fetched and
    written (``first_frame``: the current frame when None; a resumed batch job passes its
    first). ``qc`` (a :class:`~dftl_warp.output.qc.FrameQC`) adds each written frame's QC
    (:meth:`~dftl_warp.output.base.FrameWriter.write_qc`), checked against ``gates``
    (:func:`~dftl_warp.output.qc.check`: a broken gate raises QCError before the frame is
    written). ``velocities=False`` passes None velocities (``--no-velocities``).

    ``progress`` (optional) is called with the number of frames done after each one. Returns
    seconds spent simulating (launching and waiting for results), writing and on QC.
    """
    sim.last_frame = int(last_frame)   # the shot's end: the roots' velocities are one-sided there
    t_sim = t_write = t_qc = 0.0
    pending = None  # (time code, samples, qc) fetched but not yet written
    step = max(1, int(frame_step))
    base = sim.frame if first_frame is None else int(first_frame)

    def written(frame):
        return (frame - base) % step == 0

    def write(item):
        nonlocal t_write
        a = time.perf_counter()
        frame, samples, values = item
        writer.write_frame(frame, samples)
        if values is not None:
            writer.write_qc(frame, values)
        t_write += time.perf_counter() - a
        if progress is not None:
            progress(1)

    def fetch():
        nonlocal t_sim, t_qc
        a = time.perf_counter()
        samples = sim.samples(owned=False)  # written before the next fetch reuses the buffers
        if not velocities:
            samples = [(p, None) for p, _ in samples]
        b = time.perf_counter()
        t_sim += b - a
        values = None
        if qc is not None:
            values = qc.compute()
            if gates:
                from ..output.qc import check

                check(gates, sim.frame, values)
            t_qc += time.perf_counter() - b
        return sim.frame, samples, values

    if write_first:
        if written(sim.frame):
            pending = fetch()
        elif progress is not None:
            progress(1)
    while sim.frame < last_frame:
        a = time.perf_counter()
        sim.advance()
        t_sim += time.perf_counter() - a
        if pending is not None:
            write(pending)
            pending = None
        if written(sim.frame):
            pending = fetch()
        elif progress is not None:  # simulated, not written
            progress(1)
    if pending is not None:
        write(pending)
    return {"simulating": t_sim, "writing": t_write, "qc": t_qc}


def note_options(sim: Simulation, options: dict, quality: str | None, flag=str) -> None:
    """What the run's ``options`` do not do here, said before the run, not silently ignored (simulate
    and a batch job): solver options no prim's solver takes and an arithmetic without elastic prims
    (the scene's warnings), and a ``quality`` preset that leaves prims with widths on the elastic
    solver (a start note, once: a resumed batch job has it from its checkpoint). ``flag(name)``
    spells an option as the user wrote it."""
    elastic = sum(len(g.members) for g in sim.groups if g.settings.solver == "elastic")
    solvers = {g.settings.solver for g in sim.groups}
    sim.scene.warnings.extend(unused_solver_options(options, solvers, flag))
    if options.get("arithmetic") is not None and not elastic:
        sim.scene.warnings.append(f"{flag('arithmetic')} {options['arithmetic']} does nothing here: no prim runs the "
                                  f"elastic solver, whose arithmetic it sets (the others compute in the precision)")
    note = (f"quality {quality}: {plural(elastic, 'prim')} with widths {'keeps' if elastic == 1 else 'keep'} the "
            f"elastic solver, with the preset's substeps and precision (its error under a preset is not measured "
            f"yet: the presets are measured on chains, docs/accuracy-h200/front.md)")
    if quality is not None and elastic and note not in sim.start_notes:
        sim.start_notes.append(note)


def simulate_usd(input, output, *, progress: bool = False, notes=(), quality: str | None = None,
                 command: str | None = None, **options) -> Summary:
    """Simulate the hair of the USD stage ``input`` and write ``output`` (in the format its
    extension names: :func:`~dftl_warp.output.base.writer_for`).

    Keyword options are the fields of :class:`SimulationOptions` (start, end, substeps, damping,
    correction, solver, precision, device, prims); ``device=None`` picks
    :func:`~dftl_warp.core.devices.default_device`. ``progress=True`` shows progress on stderr
    (a tqdm bar on a terminal, else a line per 10 % or per minute) and, once the input is read,
    the device line and the lines ``notes`` (what a quality preset chose) on stderr.
    Bad input raises :class:`~dftl_warp.errors.UserError`; no output file is left behind on any
    failure. A missing output folder is created (removed again if the run fails). While the frames are written the
    output is locked (:mod:`dftl_warp.output.lock`): a second run on the same output fails at
    once with "OUTPUT: another dftl-warp run is writing it" instead of waiting.

    Output options (docs/caches.md): ``no_velocities``, ``frame_step`` (write every Nth frame),
    ``check`` (QC gates: a broken one raises :class:`~dftl_warp.output.qc.QCError` and leaves no
    output), ``clips`` (value clips of that many frames; 0: chosen by size). The output records
    its provenance (:mod:`dftl_warp.output.provenance`; ``quality`` is the preset named, if any)
    and each written frame's QC. Python warnings raised on the way (a collider approximated at
    any frame, numpy's RuntimeWarnings) are warnings of the run naming the input (``errors.WarningRoute``):
    the input's until the frames run, the run's from then on.
    """
    check_path("input", input)
    check_path("output", output)
    with WarningRoute(where=str(input)) as route:
        return _simulate_usd(route, input, output, progress, notes, quality, command, options)


def _simulate_usd(route, input, output, progress, notes, quality, command, options) -> Summary:
    from ..usd.read import read_scene
    from ..output.paths import check_output, output_place
    from ..output.progress import progress_bar, start_line, stderr_line
    from ..output import check_output_path, writer_for
    from ..core.devices import device_line, init_warp, resolve_device

    from ..options import OUTPUT_OPTIONS, check_api, check_keywords
    from ..output import provenance
    from ..output.qc import FrameQC, parse_gates
    from ..output.clips import start_writers_early

    parse_gates(options.get("check"), name="check")  # a bad gate in the gates' words (the CLI checked its own)
    out_opts = {k: check_api(k, options.pop(k, None)) for k in OUTPUT_OPTIONS}
    tolerance = check_api("tolerance", options.pop("tolerance", None))  # simulation.tolerance
    from ..options import GUIDE_OPTIONS
    from ..guides.scene import check_guides_output

    guides = {k: check_api(k, options.pop(k, None)) for k in GUIDE_OPTIONS}  # guides.scene (issue 22)
    if "device" in options and options["device"] is None:
        options = {**options, "device": resolve_device(None)}
    check_keywords(options, SimulationOptions, "simulate_usd")   # a misspelt keyword: did you mean
    opts = SimulationOptions(**options, quality=quality)
    gates = parse_gates(out_opts["check"])
    init_warp()
    t0 = time.perf_counter()
    check_output(check_output_path(output, input), input)   # and: not a layer the input uses
    scene = read_scene(input, prims=opts.prims, time=opts.start)
    route.where = scene.source
    route.keep_in(scene.warnings)   # said before the run, with the input's
    first, last = resolve_frames(scene, opts.start, opts.end)
    frame_range_note(scene, first, last)   # frames outside the stage's animated range: a warning
    step = out_opts["frame_step"] or 1
    last_written = last_written_frame(scene, first, last, step, "--frame-step" if command else "frame_step")
    check_guides_output(scene, guides, cli=command is not None)   # --guides-output with no guides
    if not out_opts["no_clips"]:  # clips: their writer processes start while the simulation sets up
        start_writers_early(scene, output, out_opts["clips"], (last - first) // (out_opts["frame_step"] or 1) + 1)
    sim = Simulation(scene, opts, first, tolerance=tolerance, guides=guides,
                     device_option="--device" if command else "device")
    note_options(sim, options, quality, (lambda name: f"--{name}") if command else str)
    if sim.guides is not None and sim.guides.output == "binding" and out_opts["clips"] is not None:
        raise UserError(f"{output}: --guides-output binding cannot be written as --clips")
    if out_opts["no_clips"] and out_opts["clips"] is not None:
        raise UserError(f"{output}: --clips and --no-clips contradict each other")
    if out_opts["clips"] is None and not out_opts["no_clips"] and (sim.guides is None or sim.guides.output != "binding"):
        from ..output.clips import auto_clips  # large outputs: clips (measured size, docs/caches.md)

        out_opts["clips"] = auto_clips(sim.output_scene, (last_written - first) // step + 1, output)
    shown = quality if quality is None or tolerance is None else f"{quality} (solver and substeps chosen by tolerance)"
    record = provenance.build(sim, input, quality=shown, command=command, output_options={
        "frame_step": step, "velocities": not out_opts["no_velocities"], "check": out_opts["check"] or "none",
        "clips": "none" if out_opts["clips"] is None else out_opts["clips"]})
    qc = FrameQC(sim)
    t_load = time.perf_counter() - t0
    ahead = list(scene.warnings)   # the input's and the set-up's: said before the run (a long one can be stopped)
    if progress:   # every line "dftl-warp: ...", the warnings "dftl-warp: warning: ..."
        infos = (*(sim.guides.notes() if sim.guides else ()), *(sim.tolerance.notes if sim.tolerance else ()))
        for line in (*notes, *(stderr_line(w, warning=True) for w in ahead), *map(start_line, sim.start_notes),
                     *map(stderr_line, infos), device_line(sim.options.device)):
            print(line, file=sys.stderr)

    with output_place(output):   # missing folders made (gone again on failure), the output lock held
        bar = None
        if progress:
            bar = progress_bar(last_written - first + 1, desc="simulating", unit="frame")
            sim.on_warning = lambda message: bar.write(f"dftl-warp: warning: {message}", file=sys.stderr)
        route.say = once(sim.warn, ahead)   # from now on a warning of the run, said as it comes with progress
        try:
            cls = writer_for(output)
            extra = {}
            if out_opts["no_velocities"]:
                if "velocities" not in cls.create_options:
                    raise UserError(f"{output}: the {cls.__name__} cannot leave out velocities")
                extra["velocities"] = False
            if out_opts["clips"] is not None:
                from ..output.clips import create_clips

                opened = create_clips(output, sim.output_scene, frames=(first, last_written), clip_frames=out_opts["clips"],
                                      step=step, **extra)
            else:
                opened = cls.create(output, sim.output_scene, frames=(first, last_written), **extra)
            with opened as writer:
                writer.set_record(provenance.RECORD, record)
                times = run_frames(sim, writer, last_written, progress=bar.update if bar else None, frame_step=step,
                                   qc=qc, gates=gates, velocities=not out_opts["no_velocities"])
                for text in scene.warnings[len(ahead):]:   # found while running: said as the run's are
                    sim.warn(text)
                a = time.perf_counter()
                if sim.tolerance is not None:   # the estimated error per frame and the choices
                    from .tolerance import RECORD

                    writer.set_record(RECORD, sim.tolerance.record())
                if sim.guides is not None and sim.guides.output == "binding":   # the binding as primvars
                    sim.guides.write_binding(writer.layer)   # before the commit moves the output into place
                writer.commit()
                times["writing"] += time.perf_counter() - a
        finally:
            if bar is not None:
                bar.close()
    return Summary(
        output=str(output),
        prims=len(scene.curves),
        strands=sim.num_strands,
        particles=sim.num_points,
        frames=(last_written - first) // step + 1,
        first_frame=first,
        last_frame=last_written,
        colliders=len(scene.colliders),
        seconds_loading=t_load,
        seconds_simulating=times["simulating"],
        seconds_writing=times["writing"],
        groups=[{**asdict(g.settings), "prims": len(g.members), "strands": g.num_strands,
                 "features": sorted(g.model.feature_flags)} for g in sim.groups],
        warnings=ahead + list(sim.start_notes),
        run_warnings=list(sim.warnings),
        tolerance=sim.tolerance.lines() if sim.tolerance is not None else [],
        start_notes=list(sim.start_notes),
    )
