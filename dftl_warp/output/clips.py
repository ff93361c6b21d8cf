"""USD value clips output (``simulate --clips [FRAMES]``, UsdClipsAPI; docs/caches.md).

``OUTPUT`` (e.g. ``shot.usdc``) is a small layer that sublayers a topology layer and the input and
holds, on each simulated prim, the clip set ``default``: ``assetPaths`` (one crate layer per chunk
of FRAMES frames), ``primPath``, ``active``, ``times`` and ``manifestAssetPath``. Every USD
consumer therefore sees one animated stage. Next to it, in ``shot_clips/``:

- ``topology.usdc``: the ``over`` prims and the attribute specs (points, velocities, extent), no
  samples: the topology layer (sublayered by the output) and the clips' manifest
  (``manifestAssetPath``);
- ``clip.NNNN.usdc``: the time samples of chunk NNNN.

The layers are authored by writer processes (:mod:`.clip_pool`, :mod:`.clip_process`), one per
core (at most 8): each frame is copied into shared memory and authored into its
chunk's layer by the process that holds the chunk while the frame loop goes on; when a chunk's
last frame is in, its process saves it. Processes, not threads: authoring and ``Sdf.Layer.Save``
hold Python's interpreter lock for most of their time, so threads took turns (docs/caches.md).
``simulate`` starts the processes before its set-up (:func:`start_writers_early`).
Everything is written under hidden partial names and moved into place by
:meth:`ClipsWriter.commit` (the output layer last), so an interrupted run leaves no output.
Records and QC live in the output layer. A writer failure is one :class:`UserError` line naming
the chunk. ``batch`` resumes per finished chunk (:class:`ClipsWriter`, :meth:`ClipsWriter.reopen`).
Without ``--clips``, :func:`auto_clips` chooses clips above a measured size.
"""

from __future__ import annotations

import contextlib
import os
import shutil
from pathlib import Path

from ..durable import replace_folder
from ..errors import UserError
from .base import FrameWriter, ensure_folder
from .clip_pool import ClipWriterPool, writer_count
from .usd import UsdWriter, check_output_path, uses_clips_folder

#: the clip set's name
CLIP_SET = "default"
#: ``--clips`` with no value: frames per clip chosen so that a clip holds about this many bytes
AUTO_CLIP_BYTES = 256 << 20
#: writer processes; None: one per core, at most 8 (:func:`.clip_pool.writer_count`)
WRITERS: int | None = None
#: fsync each clip layer (in its writer process, while the next chunk is authored) before it
#: counts as saved; off: the commit fsyncs every clip once, before it renames the folder into place
FSYNC = False


#: the output layer's record of the finished chunks (batch resume; removed at commit)
CHUNKS_RECORD = "dftl_warp_clips"


def clips_folder(output: Path) -> Path:
    return output.with_name(output.stem + "_clips")


def clips_partial_folder(output: Path) -> Path:
    """The hidden folder the chunks are written into before :meth:`ClipsWriter.commit`."""
    output = Path(output)
    return output.with_name(f".{clips_folder(output).name}.dftl-partial")


def check_clips_folder(output: Path) -> None:
    """Refuse clips whose folder another output's layer uses: ``shot.usdc`` and ``shot.usd`` share
    ``shot_clips/``, and writing one's clips would silently replace the other's animation."""
    folder = clips_folder(output)
    for ext in (".usdc", ".usd"):
        other = output.with_suffix(ext)
        if other.suffix.lower() != output.suffix.lower() and uses_clips_folder(other, folder):
            raise UserError(f"{output}: its value clips would replace those of {other} in {folder}: "
                            f"give the output another name")


def _clip_name(index: int) -> str:
    return f"clip.{index:04d}.usdc"


#: automatic clips (no ``--clips``): (points per frame, written frames) from which clips wrote
#: faster than one layer (``scripts/bench_clips_threshold.py``, docs/caches.md "Chosen
#: automatically"): with fewer than :data:`MANY_WRITERS` writer processes (the 2-core VM: 2) and
#: with that many or more (the 16-core H200 machine: 8)
AUTO_MIN_FEW_WRITERS = (320_000, 24)
AUTO_MIN_MANY_WRITERS = (160_000, 16)
MANY_WRITERS = 8


def auto_minimum(writers: int) -> tuple[int, int]:
    """The automatic clips' (points per frame, written frames) thresholds for ``writers`` writer
    processes."""
    return AUTO_MIN_MANY_WRITERS if writers >= MANY_WRITERS else AUTO_MIN_FEW_WRITERS


#: this machine's thresholds (its writer processes: :func:`.clip_pool.writer_count`)
AUTO_MIN_POINTS, AUTO_MIN_FRAMES = auto_minimum(writer_count(WRITERS))
#: automatic clips: at least this many chunks (so that the writers overlap)
AUTO_MIN_CHUNKS = 8


def auto_clips(scene, frames_written: int, output) -> int | None:
    """Clip length (frames) chosen for an output given no ``--clips``, or None for one layer:
    clips when a frame has :data:`AUTO_MIN_POINTS` points or more and :data:`AUTO_MIN_FRAMES`
    frames or more are written, to a crate output (``.usdc``/``.usd``)."""
    if Path(os.fspath(output)).suffix.lower() not in (".usdc", ".usd"):
        return None
    points = sum(c.num_points for c in scene.curves)
    if points < AUTO_MIN_POINTS or frames_written < AUTO_MIN_FRAMES:
        return None
    return max(1, min(auto_clip_frames(scene), -(-frames_written // AUTO_MIN_CHUNKS)))


def start_writers_early(scene, output, clips: int | None, frames_written: int) -> None:
    """Start the writer processes now when ``output`` will be written as clips (``clips`` given,
    or :func:`auto_clips` on ``scene``), so that their start overlaps the simulation's set-up
    (:func:`.clip_pool.start_early`); the :class:`ClipsWriter` made next takes them."""
    from .clip_pool import start_early

    if clips is not None or auto_clips(scene, frames_written, output) is not None:
        start_early(WRITERS)


def auto_clip_frames(scene, velocities: bool = True) -> int:
    points = sum(c.num_points for c in scene.curves)
    per_frame = max(1, points * (24 if velocities else 12))
    return max(1, AUTO_CLIP_BYTES // per_frame)


def _write_clip(path: Path, pool: ClipWriterPool, index: int) -> None:
    """:func:`_author_clip`; any failure becomes a one-line UserError naming the chunk."""
    from pxr import Tf

    try:
        _author_clip(path, pool, index)
    except UserError:
        raise
    except Tf.ErrorException as exc:
        from .usd import _tf_error

        raise UserError(f"{path}: cannot write the clip: {_tf_error(exc)}") from None
    except OSError as exc:
        raise UserError(f"{path}: cannot write the clip: {exc.strerror or exc}") from None


def _author_clip(path: Path, pool: ClipWriterPool, index: int) -> None:
    """The crate layer ``path`` of chunk ``index``, authored and saved by its writer process
    (:mod:`.clip_process`): waits for it and raises the error the process met (OSError, or the USD
    message)."""
    error = pool.result(index)
    if error is None:
        return
    if error[0] == "os":
        raise OSError(error[1], error[2])
    raise UserError(f"{path}: cannot write the clip: {error[1]}")


class ClipsWriter(FrameWriter):
    """The :class:`FrameWriter` of a value-clips output (made by :func:`create_clips`).

    Resumable per chunk (batch): a chunk's layer is saved under a hidden name and renamed into the
    partial folder once whole; :meth:`flush` waits for every handed-over chunk and records the
    finished chunks (index and time codes) in the output layer's record :data:`CHUNKS_RECORD`,
    so a checkpoint copy of the output layer names exactly the chunks that are complete on disk.
    :meth:`reopen` keeps those and drops any other chunk file.
    """

    resumable = True

    def __init__(self, output: Path, scene, frames, clip_frames: int, velocities: bool, *, top=None,
                 keep_partial: bool = False, chunks=None, step: int = 1):
        self.output = output
        self.scene = scene
        self.first, self.last = frames
        self.clip_frames = int(clip_frames)
        self.velocities = velocities
        self.step = max(1, int(step))
        self.keep_partial = keep_partial
        #: a resumable (batch) writer keeps its chunk folder on abort: the checkpoint names chunks in it
        self.keep_chunks = keep_partial
        self.folder = clips_folder(output)
        self.partial_folder = clips_partial_folder(output)
        if top is None:
            shutil.rmtree(self.partial_folder, ignore_errors=True)
            self.partial_folder.mkdir()
            # the output layer: metadata, sublayers, over specs, records and QC (a UsdWriter's layer)
            top = UsdWriter.create(output, scene, frames=frames, velocities=velocities, keep_partial=keep_partial)
        self.top = top
        self.targets = [(c.path, t.widths) for c, t in zip(scene.curves, self.top.targets)]
        self._chunk: list[float] = []  # time codes of the chunk being handed over frame by frame
        self._chunk_index = None
        #: finished or handed-over chunks: (index, [time codes])
        self._clips: list[tuple[int, list[float]]] = list(chunks or [])
        #: handed-over chunks whose save is not yet confirmed: (index, path)
        self._unconfirmed: list[tuple[int, Path]] = []
        self._written: list[float] = [t for _, times in self._clips for t in times]
        try:
            self._pool = ClipWriterPool(self.targets, [c.num_points for c in scene.curves], velocities,
                                        writers=WRITERS, fsync=FSYNC, name=str(output))
        except BaseException:
            self.top.keep_partial = keep_partial
            self.top.abort()
            raise

    @classmethod
    def partial_path(cls, output) -> Path:
        return UsdWriter.partial_path(output)

    @classmethod
    def reopen(cls, output, scene, *, keep_partial: bool = True, frames=None, clip_frames: int = 0,
               step: int = 1):
        """Continue the partial output of ``output``: its output layer (:meth:`UsdWriter.reopen`)
        and the chunks its record names; other chunk files in the partial folder are dropped."""
        import json

        output = Path(os.fspath(output))
        folder = clips_partial_folder(output)
        if not folder.is_dir():
            raise UserError(f"{output}: no partial clips folder {folder} to continue")
        top = UsdWriter.reopen(output, scene, keep_partial=keep_partial)
        record = top.record(CHUNKS_RECORD) or {}
        try:
            chunks = [(int(i), [float(t) for t in times]) for i, times in json.loads(record.get("chunks", "[]"))]
        except (TypeError, ValueError):
            raise UserError(f"{output}: unreadable clips record in the partial output") from None
        if int(record.get("clip_frames", -1)) != int(clip_frames):
            raise UserError(f"{output}: the partial output has clips of other lengths")
        keep = {_clip_name(i) for i, _ in chunks}
        for path in folder.iterdir():
            if path.name not in keep:
                path.unlink()
        missing = sorted(keep - {p.name for p in folder.iterdir()})
        if missing:
            raise UserError(f"{output}: the partial clips folder lacks {missing[0]}")
        first, last = frames if frames is not None else (None, None)
        velocities = any(t.velocities is not None for t in top.targets)
        writer = cls(output, scene, (first, last), clip_frames, velocities, top=top, keep_partial=keep_partial,
                     chunks=chunks, step=step)
        writer.keep_chunks = True  # still the checkpoint's chunks until commit
        return writer

    def write_frame(self, time_code: float, samples) -> None:
        index = self._chunk_of(int(round(time_code)))
        if self._chunk and index != self._chunk_index:
            self._submit()
        self._chunk_index = index
        self._pool.put_frame(index, self.partial_folder / _clip_name(index), time_code, samples)  # copied now
        self._chunk.append(float(time_code))
        self._written.append(float(time_code))
        following = int(round(time_code)) + self.step
        if following > self.last or self._chunk_of(following) != index:
            self._submit()  # the chunk is whole: hand it over now (a checkpoint may follow)

    def _chunk_of(self, frame: int) -> int:
        """The chunk of a written frame: ``clip_frames`` written frames a chunk, as :func:`auto_clips`
        and :func:`auto_clip_frames` count them (with ``--frame-step N``, N times as many simulated)."""
        return (frame - self.first) // self.step // self.clip_frames

    @property
    def chunks_handed_over(self) -> int:
        """Chunks handed to the writers (or kept from a resumed run) so far."""
        return len(self._clips)

    @property
    def at_chunk_boundary(self) -> bool:
        """No written frame waits in an unfinished chunk (a checkpoint now keeps every frame)."""
        return not self._chunk

    def _submit(self) -> None:
        times, index = self._chunk, self._chunk_index
        self._chunk = []
        self._clips.append((index, times))
        self._pool.save(index)
        self._unconfirmed.append((index, self.partial_folder / _clip_name(index)))
        self._confirm(wait=False)  # a failed chunk stops the run early

    def _confirm(self, wait: bool) -> None:
        """Check the handed-over chunks' saves, in order (``wait``: all of them; else those answered)."""
        while self._unconfirmed and (wait or self._pool.done(self._unconfirmed[0][0])):
            index, path = self._unconfirmed.pop(0)
            _write_clip(path, self._pool, index)

    def write_qc(self, time_code: float, qc: dict) -> None:
        self.top.write_qc(time_code, qc)

    def flush(self) -> None:
        """Wait for the handed-over chunks, record them and save the output layer."""
        import json

        self._confirm(wait=True)
        self.top.set_record(CHUNKS_RECORD, {"clip_frames": self.clip_frames,
                                            "chunks": json.dumps([[i, times] for i, times in self._clips])})
        self.top.flush()

    @property
    def written_time_codes(self) -> list[float]:
        return list(self._written)

    @property
    def is_open(self) -> bool:
        return self.top is not None

    def set_record(self, name: str, record: dict) -> None:
        self.top.set_record(name, record)

    def record(self, name: str) -> dict | None:
        return self.top.record(name)

    @classmethod
    def read_record(cls, path, name: str) -> dict | None:
        return UsdWriter.read_record(path, name)

    def commit(self) -> Path:
        from pxr import Sdf, Vt

        try:
            if self._chunk:
                self._submit()
            self._confirm(wait=True)
            self._pool.close()
            with contextlib.suppress(KeyError):  # the chunk list is a batch record, not the output's
                self.top.layer.customLayerData = {k: v for k, v in dict(self.top.layer.customLayerData).items()
                                                  if k != CHUNKS_RECORD}
            # topology: the top layer's over specs without samples (and without records or QC)
            topology = Sdf.Layer.CreateNew(str(self.partial_folder / "topology.usdc"))
            for path_, _ in self.targets:
                Sdf.CreatePrimInLayer(topology, path_).specifier = Sdf.SpecifierOver
                Sdf.CopySpec(self.top.layer, path_, topology, path_)
            topology.Save()
            layer = self.top.layer
            rel = f"./{self.folder.name}"
            layer.subLayerPaths.insert(0, f"{rel}/topology.usdc")
            for path_, _ in self.targets:  # the samples come from the clips; the specs from the topology
                prim = layer.GetPrimAtPath(path_)
                for name in ("points", "velocities", "extent"):
                    attr = prim.attributes.get(name)
                    if attr is not None:
                        prim.RemoveProperty(attr)
            # the clip metadata (UsdClipsAPI's ``clips`` dictionary), authored with Sdf: no stage is
            # opened on the partial layer, whose relative paths resolve only once it is in place
            assets = Sdf.AssetPathArray([f"{rel}/{_clip_name(i)}" for i, _ in self._clips])
            spans = [(i, ts[0], ts[-1]) for i, ts in self._clips]
            active = Vt.Vec2dArray([(t0, float(k)) for k, (_, t0, _) in enumerate(spans)])
            times = []
            for _, t0, t1 in spans:
                times += [(t0, t0)] + ([(t1, t1)] if t1 != t0 else [])
            for path_, _ in self.targets:
                layer.GetPrimAtPath(path_).SetInfo("clips", {CLIP_SET: {
                    "assetPaths": assets, "primPath": path_, "active": active, "times": Vt.Vec2dArray(times),
                    "manifestAssetPath": Sdf.AssetPath(f"{rel}/topology.usdc")}})  # topology = manifest
            shutil.rmtree(self.folder, ignore_errors=True)
            replace_folder(self.partial_folder, self.folder)   # every clip on the disk, then renamed
            self.top.keep_partial = self.keep_partial
            out = self.top.commit()
            self.top = None
            return out
        except BaseException:
            self.keep_partial = False
            self.abort()
            raise

    def abort(self) -> None:
        """Drop the partial output (unless ``keep_partial``: batch resumes from its checkpoint)."""
        self._pool.kill()  # before the partial folder goes: no process writes into it any more
        if self.top is not None and self.top.is_open:
            self.top.keep_partial = self.keep_partial
            self.top.abort()
        self.top = None
        if not (self.keep_partial or self.keep_chunks):
            shutil.rmtree(self.partial_folder, ignore_errors=True)


def create_clips(output, scene, *, frames, clip_frames: int = 0, velocities: bool = True,
                 keep_partial: bool = False, step: int = 1) -> ClipsWriter:
    """A :class:`ClipsWriter` for ``output`` (``clip_frames`` 0: :func:`auto_clip_frames`);
    ``step``: the distance between written frames (``--frame-step``)."""
    output = check_output_path(output, scene.source)
    if output.suffix.lower() == ".usda":
        raise UserError(f"{output}: --clips writes a .usdc or .usd output layer")
    check_clips_folder(output)
    ensure_folder(output)
    frames = (int(frames[0]), int(frames[1]))
    return ClipsWriter(output, scene, frames, clip_frames or auto_clip_frames(scene, velocities), velocities,
                       keep_partial=keep_partial, step=step)
