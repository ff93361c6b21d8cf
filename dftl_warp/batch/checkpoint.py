"""One batch job, resumable: simulate a stage to its output with regular checkpoints.

Files next to ``OUTPUT`` (``out/sh010.usdc``), all hidden and all gone once the job completes:

- ``.sh010.usdc.dftl-partial.usdc``: the frames being written (the output's
  :class:`~dftl_warp.output.base.FrameWriter`, :meth:`~dftl_warp.output.base.FrameWriter.partial_path`);
- ``.sh010.usdc.dftl-checkpoint.usdc``: a copy of the partial file at the last checkpoint (same suffix);
- ``.sh010.usdc.dftl-checkpoint.npz``: the solver state at that frame
  (:meth:`~dftl_warp.simulation.simulate.Simulation.save_state`), the job's settings hash and state layout,
  the clean start's lines (a resumed job repeats them: it moves hair out of colliders again, which
  sets elastic strands' rest shapes, but does not step the preroll, whose result the state replaces)
  and the run's warnings so far (repeated too: energy growth, a collider approximated, a fast turn);
- ``.sh010.usdc.dftl-lock``: held (``flock``) while a process works on the job.

A checkpoint is taken every ``every_frames`` frames and/or ``every_seconds`` seconds: the partial
file is saved, copied to a temporary file and renamed over the checkpoint copy, then the state is
written to a temporary ``.npz`` and renamed. Every file is therefore whole at any moment, and the
copy is never older than the state (frames past the state's frame are simply written again, to
the same values). USD saves a crate file in place, so the live partial file is never trusted
after an interruption: a resumed job starts from the checkpoint copy.

A job is *complete* when ``OUTPUT`` exists and its writer's record :data:`LAYER_DATA_KEY` (for USD:
the layer's ``customLayerData``) holds the job's settings hash (contents of the input and of every file it depends on, frames and options; see
:func:`settings_hash`). A checkpoint is used
only when it records the same hash and state layout; otherwise it is discarded and the job starts
over. Completed jobs are skipped.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import re
import shutil
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from ..durable import replace_file
from ..errors import UserError, WarningRoute, once

#: version of the checkpoint and completion records (bump when their meaning changes); 2: clips of
#: a job with a frame step count written frames (commit d7d9519), so a checkpoint of format 1 would
#: resume with the clips numbered the other way
FORMAT = 2
#: name of the output's record (:meth:`~dftl_warp.output.base.FrameWriter.set_record`; USD: the
#: ``customLayerData`` key) holding the batch record
LAYER_DATA_KEY = "dftl_warp_batch"
#: how long a job waits for the lock of its output held by another (e.g. dying) process, s
LOCK_WAIT_SECONDS = 30.0


@dataclass
class CheckpointPolicy:
    """When to checkpoint: every ``every_frames`` frames and/or every ``every_seconds`` seconds of
    wall time (0 turns either off). Checkpoints by time also wait long enough that taking them
    costs at most ``max_overhead`` of the job's time (a checkpoint copies the frames written so
    far, which grows with the output)."""

    every_frames: int = 0
    every_seconds: float = 30.0
    max_overhead: float = 0.05


@dataclass
class JobResult:
    """What happened to one job. ``status``: done, skipped (already complete) or failed."""

    index: int
    name: str
    output: str
    status: str
    device: str | None = None
    #: frames of the job's range, and frames simulated and written by this run
    total_frames: int = 0
    frames: int = 0
    #: frame the run continued from (a checkpoint), or None
    resumed_from: int | None = None
    #: wall time of the job in this run, s
    seconds: float = 0.0
    error: str | None = None
    notes: list[str] = field(default_factory=list)
    #: what ``simulate`` prints as warnings: the input's (unknown attributes, frames outside the
    #: stage's range), the clean start's (hair moved out of colliders, a preroll not settled or
    #: not run) and the run's (energy growth), in order
    warnings: list[str] = field(default_factory=list)

    @property
    def ok(self) -> bool:
        return self.status in ("done", "skipped")

    @property
    def frames_per_second(self) -> float:
        return self.frames / self.seconds if self.seconds > 0 else 0.0

    def as_dict(self) -> dict:
        return asdict(self)


@dataclass(frozen=True)
class JobFiles:
    """The hidden files of a job next to its output."""

    output: Path

    def _sibling(self, suffix: str) -> Path:
        return self.output.with_name(f".{self.output.name}.{suffix}")

    @property
    def partial(self) -> Path:
        from ..output import writer_for

        return writer_for(self.output).partial_path(self.output)

    @property
    def checkpoint_usd(self) -> Path:
        """The checkpoint copy of the partial file (same suffix as the partial file)."""
        return self._sibling("dftl-checkpoint" + self.partial.suffix)

    @property
    def checkpoint_state(self) -> Path:
        return self._sibling("dftl-checkpoint.npz")

    @property
    def lock(self) -> Path:
        from ..output.lock import lock_path

        return lock_path(self.output)

    def temporary(self, path: Path) -> Path:
        return path.with_name(path.name + ".tmp")

    def checkpoint_files(self) -> list[Path]:
        files = [self.checkpoint_usd, self.checkpoint_state]
        return files + [self.temporary(p) for p in files]


# -- settings ---------------------------------------------------------------------------------------


# the one input fingerprint (also the provenance record's, dftl_warp.output.provenance)
from ..output.provenance import file_sha256, input_fingerprint  # noqa: E402,F401  (re-exported)


def settings_hash(input_path, output, options, first: int, last: int, output_options: dict | None = None,
                  fingerprint: dict | None = None) -> str:
    """Hash of everything the output depends on: the contents of the input and of every file it
    depends on, the input and output paths, the frame range and the simulate options (except the
    device: every device gives the same results). ``options`` is a
    :class:`~dftl_warp.simulation.simulate.SimulationOptions`."""
    from ..version import __version__

    opts = {k: v for k, v in asdict(options).items() if k not in ("device", "start", "end")}
    record = {
        "format": FORMAT,
        "dftl_warp": __version__,
        "input": os.path.abspath(input_path),
        "files": fingerprint if fingerprint is not None else input_fingerprint(input_path),
        "output": os.path.abspath(output),
        "frames": [int(first), int(last)],
        "options": opts,
    }
    if output_options:  # --frame-step, --no-velocities, --check, --clips (only when set: older hashes hold)
        record["output_options"] = {k: v for k, v in sorted(output_options.items()) if v is not None}
    return hashlib.sha256(json.dumps(record, sort_keys=True).encode()).hexdigest()


def state_signature(sim) -> str:
    """What a saved state's layout depends on: device kinds and the arrays' shapes and types."""
    from ..core.devices import parse_devices

    kinds = ",".join("cuda" if d.startswith("cuda") else d for d in parse_devices(sim.options.device))
    shapes = {k: [list(np.shape(v)), str(np.asarray(v).dtype)] for k, v in sim.save_state().items()
              if k != "frame" and ".monitor." not in k}   # the energy check's records: not the layout
    return json.dumps({"devices": kinds, "arrays": shapes}, sort_keys=True)


def completed(output, key: str) -> bool:
    """Whether ``output`` exists and was written by a job with settings hash ``key`` (its
    writer's record :data:`LAYER_DATA_KEY`)."""
    from ..output import completed as has_record

    return has_record(output, LAYER_DATA_KEY, key)


# -- files ------------------------------------------------------------------------------------------


def _remove(path) -> None:
    with contextlib.suppress(FileNotFoundError):
        os.remove(path)


def _copy(source: Path, target: Path) -> None:
    """Copy a file in the kernel (``copy_file_range``: a reflink clone on file systems that have
    them), else through ``shutil``."""
    if hasattr(os, "copy_file_range"):
        try:
            with open(source, "rb") as src, open(target, "wb") as dst:
                size = os.fstat(src.fileno()).st_size
                copied = 0
                while copied < size:
                    n = os.copy_file_range(src.fileno(), dst.fileno(), size - copied)
                    if n == 0:
                        break
                    copied += n
            if copied == size:
                return
        except OSError:
            pass
    shutil.copyfile(source, target)


def atomic_copy(source: Path, target: Path, tmp: Path) -> None:
    """Copy ``source`` to ``target`` through ``tmp`` (whole file or nothing at ``target``)."""
    _copy(source, tmp)
    replace_file(tmp, target)


def atomic_savez(target: Path, tmp: Path, arrays: dict) -> None:
    with open(tmp, "wb") as f:
        np.savez(f, **arrays)
    replace_file(tmp, target)


def remove_job_files(files: JobFiles) -> None:
    """Delete the partial and checkpoint files of a job, and the temporary files USD leaves
    when killed while exporting a partial file (``.NAME.dftl-partial.XXXXXX``)."""
    import glob

    leftovers = files.output.parent.glob(glob.escape(f".{files.output.name}.dftl-partial") + "*")
    for path in [files.partial, *files.checkpoint_files(), *leftovers]:
        _remove(path)
    from ..output.clips import clips_partial_folder

    shutil.rmtree(clips_partial_folder(files.output), ignore_errors=True)  # a clips job's chunks


def clean_interrupted(output) -> bool:
    """After the process working on ``output`` was killed (a crashed worker, an interrupted
    batch): remove what only a live run uses -- the partial file, USD's temporary files of it,
    half-written checkpoint temporaries and the lock file -- and keep the checkpoint a rerun
    resumes from (a value-clips job's finished chunks too). Returns False, touching nothing, when
    another process holds the job's lock (or it cannot be taken)."""
    import glob

    files = JobFiles(Path(output))
    try:
        with job_lock(files.lock, wait=0.0):   # removed again on leaving
            leftovers = files.output.parent.glob(glob.escape(f".{files.output.name}.dftl-partial") + "*")
            for path in [files.partial, *leftovers, *(files.temporary(p) for p in
                                                      (files.checkpoint_usd, files.checkpoint_state))]:
                _remove(path)
    except (UserError, OSError):
        return False
    return True


def job_lock(path: Path, wait: float | None = None):
    """Exclusive lock on ``path`` (created, removed on exit) so that two processes never work on
    the same output; waits up to ``wait`` s (default ``LOCK_WAIT_SECONDS``) for a holder (e.g. a
    process being killed). The lock :func:`dftl_warp.output.lock.output_lock` that ``simulate``
    takes too."""
    from ..output.lock import output_lock

    return output_lock(path, LOCK_WAIT_SECONDS if wait is None else wait)


# -- running ----------------------------------------------------------------------------------------


def run_job(job, device: str, policy: CheckpointPolicy | None = None, progress=None) -> JobResult:
    """Run :class:`~dftl_warp.batch.jobs.Job` ``job`` on ``device``, resuming from its checkpoint when
    one matches. Never raises for the job's own problems: they come back as a failed result.

    ``progress`` (optional) is called with event dicts: ``{"event": "start", "total", "first",
    "last", "resumed_from"}``, ``{"event": "frames", "done"}``, ``{"event": "note", "text"}``,
    ``{"event": "warning", "text"}`` (each also kept in :attr:`JobResult.warnings`).
    """
    policy = policy or CheckpointPolicy()
    start = time.perf_counter()
    result = JobResult(index=job.index, name=job.name, output=job.output, status="failed", device=device)
    emit = progress or (lambda event: None)
    if job.error is not None:
        result.error = job.error
        return result
    try:
        from ..output import check_output_path
        from ..output.paths import created_folders

        files = JobFiles(Path(job.output))
        check_output_path(job.output)   # a folder that is a file, ...: simulate's one line, not an OSError
        # a failed job leaves no new empty folder (one holding its checkpoint stays: a rerun resumes)
        # Python warnings (a collider approximated, numpy's RuntimeWarnings): the job's, naming its input
        with created_folders(job.output), job_lock(files.lock), WarningRoute(where=job.input) as route:
            _run(job, device, policy, files, result, emit, route)
    except UserError as exc:
        result.status, result.error = "failed", str(exc)
    except Exception as exc:  # a bug or an environment problem: one line, details on request
        if os.environ.get("DFTL_WARP_VERBOSE"):
            import traceback

            traceback.print_exc()
        result.status, result.error = "failed", f"{job.output}: internal error: {type(exc).__name__}: {exc}"
    result.seconds = time.perf_counter() - start
    return result


def _run(job, device, policy, files: JobFiles, result: JobResult, emit, route) -> None:
    from ..simulation.simulate import Simulation, SimulationOptions, note_options, resolve_frames, run_frames
    from ..simulation.settings import frame_range_note, last_written_frame
    from ..usd.read import read_scene
    from ..output import check_output_path, writer_for
    from ..output.paths import check_not_a_dependency
    from ..core.devices import init_warp

    from ..options import OUTPUT_OPTIONS
    from ..output import provenance
    from ..output.progress import is_plain_note
    from ..output.qc import FrameQC, parse_gates

    def note(text):
        result.notes.append(text)
        emit({"event": "note", "text": text})

    def warn(text):
        result.warnings.append(text)
        emit({"event": "warning", "text": text})

    init_warp()
    options = dict(job.options)
    out_opts = {k: options.pop(k, None) for k in OUTPUT_OPTIONS}  # --frame-step, --check, ... (docs/caches.md)
    opts = SimulationOptions(**options, device=device)
    gates = parse_gates(out_opts["check"])
    step = out_opts["frame_step"] or 1
    check_output_path(job.output, job.input)
    check_not_a_dependency(job.output, job.input)   # nor a layer the input uses
    scene = read_scene(job.input, prims=opts.prims, time=opts.start)
    route.where = scene.source
    route.keep_in(scene.warnings)   # given with the input's (those of the set-up after it)
    first, last = resolve_frames(scene, opts.start, opts.end)
    frame_range_note(scene, first, last)   # frames outside the stage's animated range (as simulate)
    last = last_written_frame(scene, first, last, step, "frame_step")  # the last frame written
    for text in scene.warnings:   # unknown attributes, ...: what simulate prints as warnings
        warn(text)
    shown = len(scene.warnings)
    if out_opts["no_clips"] and out_opts["clips"] is not None:
        raise UserError(f"{job.output}: clips and no_clips contradict each other")
    if out_opts["clips"] is None and not out_opts["no_clips"]:  # large outputs: clips (docs/caches.md)
        from ..output.clips import auto_clips

        out_opts["clips"] = auto_clips(scene, (last - first) // step + 1, job.output)
    result.total_frames = last - first + 1
    fingerprint = input_fingerprint(job.input)
    key = settings_hash(job.input, job.output, opts, first, last,
                        {k: v for k, v in out_opts.items() if v is not None}, fingerprint=fingerprint)
    if completed(job.output, key):
        remove_job_files(files)  # left over when a run was killed right after its commit
        result.status = "skipped"
        return
    clip_frames = None
    if out_opts["clips"] is not None:  # value clips: resumable per finished chunk (docs/caches.md)
        from ..output.clips import auto_clip_frames

        clip_frames = out_opts["clips"] or auto_clip_frames(scene, not out_opts["no_velocities"])
    saved = _saved_state(files, key, first, last, note, clip_frames)
    # resuming: the checkpoint's state replaces the preroll's, which is not stepped (the hair is
    # still moved out of colliders: elastic strands rest where it puts them, as before the checkpoint)
    sim = Simulation(scene, opts, first, device_option="device", resuming=saved is not None)
    signature = state_signature(sim)
    writer, resumed = None, None
    if saved is not None:
        writer, resumed = _resume(files, key, saved, signature, sim, scene, first, last, note, step, clip_frames)
        if writer is None:   # unusable after all: a clean start, with its preroll
            del scene.warnings[shown:]
            sim = Simulation(scene, opts, first, device_option="device")
    note_options(sim, options, job.options.get("quality"))   # options that do nothing here, as simulate says
    qc = FrameQC(sim)   # its notes (penetration without widths) join the start notes said below
    for text in scene.warnings[shown:]:   # found while setting up (e.g. an elastic style that cannot stand)
        warn(text)
    # the clean start's lines (a resumed run: those of the run it continues): a settled preroll is a note
    for text in sim.start_notes:
        (note if is_plain_note(text) else warn)(text)
    for text in sim.warnings:   # the run's warnings before the checkpoint, given again
        warn(text)
    sim.on_warning = warn   # energy growth, as it happens
    # Python's warnings from now on: the run's (a resumed run: not those its checkpoint repeats)
    route.say = _news(once(sim.warn, scene.warnings), sim.warnings if resumed is not None else ())
    if writer is None:
        remove_job_files(files)
        extra = {"velocities": False} if out_opts["no_velocities"] else {}
        if clip_frames is not None:
            from ..output.clips import create_clips

            writer = create_clips(job.output, scene, frames=(first, last), clip_frames=clip_frames, keep_partial=True,
                                  step=step, **extra)
        else:
            writer = writer_for(job.output).create(job.output, scene, frames=(first, last), keep_partial=True, **extra)
        writer.set_record(LAYER_DATA_KEY, {"settings_hash": key, "format": FORMAT})
        writer.set_record(provenance.RECORD, provenance.build(
            sim, job.input, fingerprint=fingerprint, quality=job.options.get("quality"),
            output_options={"frame_step": step, "velocities": not out_opts["no_velocities"],
                            "check": out_opts["check"] or "none",
                            "clips": "none" if out_opts["clips"] is None else out_opts["clips"]}))
    result.resumed_from = resumed
    emit({"event": "start", "total": result.total_frames, "first": first, "last": last, "resumed_from": resumed})
    done = 0 if resumed is None else resumed - first + 1
    # the frame loop may run a frame ahead of the writer (simulate.run_frames): a checkpoint
    # saves the state at sim.frame, and a resumed run writes that frame again before going on
    since = {"frames": 0, "time": time.monotonic(), "cost": 0.0,
             "chunks": getattr(writer, "chunks_handed_over", 0)}

    def after_frame(_n):
        nonlocal done
        done += 1
        result.frames += 1
        emit({"event": "frames", "done": done})
        since["frames"] += 1
        if sim.frame >= last:
            return
        if clip_frames is not None:  # clips: a checkpoint per finished chunk, and only then
            if writer.at_chunk_boundary and writer.chunks_handed_over > since["chunks"]:
                _checkpoint(files, writer, sim, key, signature)
                since["chunks"] = writer.chunks_handed_over
            return
        due_frames = policy.every_frames and since["frames"] >= policy.every_frames
        wait = max(policy.every_seconds, since["cost"] / policy.max_overhead if policy.max_overhead > 0 else 0.0)
        due_time = policy.every_seconds and time.monotonic() - since["time"] >= wait
        if due_frames or due_time:
            began = time.monotonic()
            _checkpoint(files, writer, sim, key, signature)
            since["frames"], since["time"], since["cost"] = 0, time.monotonic(), time.monotonic() - began

    try:
        run_frames(sim, writer, last, progress=after_frame, write_first=True, frame_step=step, first_frame=first,
                   qc=qc, gates=gates, velocities=not out_opts["no_velocities"])
        writer.keep_partial = False
        writer.commit()
    except BaseException:
        writer.keep_partial = False  # the checkpoint, not the partial file, is what resumes
        if writer.is_open:
            writer.abort()
        raise
    remove_job_files(files)
    result.status = "done"


#: a number standing alone in a warning (not a part of a path or a name)
_NUMBER = re.compile(r"(?<![\w/.])[-+]?\d+(?:\.\d+)?(?:e[-+]?\d+)?(?![\w/])")


def _news(say, given=()):
    """``say`` for the run's Python warnings from now on (a collider approximated, numpy's), leaving out
    one that is a warning of ``given`` (a resumed run's, from before its checkpoint) with other
    numbers: what warns once per run (a mesh outrunning its field, by so much) was said by the run
    it continues, and the uninterrupted run says it once."""
    before = {_NUMBER.sub("#", text) for text in given}

    def news(text: str) -> None:
        if _NUMBER.sub("#", text) not in before:
            say(text)

    return news


def _checkpoint(files: JobFiles, writer, sim, key: str, signature: str) -> None:
    """Save the partial file, copy it, then save the state (see the module docstring)."""
    writer.flush()
    atomic_copy(files.partial, files.checkpoint_usd, files.temporary(files.checkpoint_usd))
    state = dict(sim.save_state())
    state["settings_hash"] = np.array(key)
    state["signature"] = np.array(signature)
    state["format"] = np.array(FORMAT)
    state["start_notes"] = np.array(sim.start_notes, dtype=str)   # a resumed run repeats them
    state["run_warnings"] = np.array(sim.warnings, dtype=str)     # and these (energy growth, colliders, ...)
    state["fast_turns"] = np.array(sorted(sim.fast_turns), dtype=str)   # prims warned about: not again
    atomic_savez(files.checkpoint_state, files.temporary(files.checkpoint_state), state)


#: what a checkpoint's .npz holds besides the simulation's state
RECORDS = ("settings_hash", "signature", "format", "start_notes", "run_warnings", "fast_turns")


def _saved_state(files: JobFiles, key, first, last, note, clip_frames=None) -> dict | None:
    """The checkpoint's saved state when it is one of these settings (its hash and format) within
    ``first..last``, else None (with a note when there was one): what is known before the
    simulation is set up, so that a resumed one skips the preroll."""
    from ..output import writer_for
    from ..output.clips import ClipsWriter

    cls = writer_for(files.output) if clip_frames is None else ClipsWriter
    if not cls.resumable:
        return None
    if not (files.checkpoint_state.exists() and files.checkpoint_usd.exists()):
        return None
    try:
        with np.load(files.checkpoint_state, allow_pickle=False) as data:
            state = {k: data[k] for k in data.files}
    except Exception as exc:  # noqa: BLE001 - any unreadable checkpoint is just discarded
        note(f"checkpoint unreadable ({type(exc).__name__}); starting over")
        return None
    if int(state.get("format", -1)) != FORMAT or str(state.get("settings_hash")) != key:
        note("checkpoint is from other settings or input; starting over")
        return None
    frame = int(state["frame"])  # the state's frame; the USD copy holds every frame before it
    if not first < frame <= last:
        note(f"checkpoint frame {frame} is outside {first}..{last}; starting over")
        return None
    return state


def _resume(files: JobFiles, key, state, signature, sim, scene, first, last, note, step: int = 1, clip_frames=None):
    """(writer, last frame kept) continuing from the checkpoint's ``state`` (:func:`_saved_state`),
    or (None, None) to start over. The simulation is left at the checkpoint's frame, which is
    written (again) next, with the clean start's lines of the run it continues.
    ``clip_frames``: a value-clips job (its finished chunks are kept, the others dropped)."""
    from ..output import writer_for
    from ..output.clips import ClipsWriter

    cls = writer_for(files.output) if clip_frames is None else ClipsWriter
    if str(state.get("signature")) != signature:
        note("checkpoint was taken on another kind of device; starting over")
        return None, None
    frame = int(state["frame"])
    atomic_copy(files.checkpoint_usd, files.partial, files.temporary(files.partial))
    try:
        if clip_frames is None:
            writer = cls.reopen(files.output, scene, keep_partial=False)
        else:
            writer = cls.reopen(files.output, scene, keep_partial=False, frames=(first, last),
                                clip_frames=clip_frames, step=step)
    except UserError as exc:
        note(f"checkpoint output unusable ({exc}); starting over")
        return None, None
    record = writer.record(LAYER_DATA_KEY) or {}
    have = set(writer.written_time_codes)
    if record.get("settings_hash") != key or not have.issuperset(range(first, frame, step)):
        writer.abort()
        note("checkpoint output does not match its state; starting over")
        return None, None
    # the run's warnings before the checkpoint, in their order (the energy check's, given again as it
    # loads, among them), said again by the resumed run; a prim warned about turning fast is not again
    sim.warnings = [str(text) for text in state.get("run_warnings", ())]
    sim.fast_turns = {str(path) for path in state.get("fast_turns", ())}
    sim.load_state({k: v for k, v in state.items() if k not in RECORDS})
    if "start_notes" in state:   # (a checkpoint without them: the push-out's, found again)
        sim.start_notes = [str(text) for text in state["start_notes"]]
    return writer, frame - 1
