"""The frame-writer interface and the registry of output formats, by file extension.

Everything above the output layer (``simulate_usd`` and the frame loop in
:mod:`dftl_warp.simulation.simulate`, the resumable batch jobs in :mod:`dftl_warp.batch.checkpoint`)
writes frames through :class:`FrameWriter` and finds the class with :func:`writer_for`; none of
them knows the file format. A writer's life:

1. ``cls.create(output, scene, frames=(first, last), keep_partial=False)``: a new partial file
   next to ``output`` (frames stream into it; an interrupted run never leaves a half-written
   output). A resumable (``keep_partial``) writer streams into ``cls.partial_path(output)``, a
   fixed name :meth:`FrameWriter.reopen` finds again;
2. ``write_frame(time_code, samples)`` per frame, in increasing time code order (``samples``: one
   ``(points, velocities)`` pair of (N, 3) arrays per ``scene.curves`` prim, local space, stage
   units and stage units per second; ``velocities`` is None for a writer created with
   ``velocities=False``, see :attr:`FrameWriter.create_options`), then optionally
   ``write_qc(time_code, qc)`` (the frame's per-prim QC, :mod:`dftl_warp.output.qc`); ``flush()`` makes what was written so far durable in the
   partial file (a batch checkpoint copies it then);
3. ``commit()`` moves the result onto ``output``; ``abort()`` drops the partial file (kept when
   ``keep_partial``). As a context manager a writer aborts on any exception.

A *record* is a small JSON-like dict a writer stores in its output under a name
(:meth:`FrameWriter.set_record`, read back with :meth:`FrameWriter.record` on a reopened writer and
:meth:`FrameWriter.read_record` on a finished file): batch keeps each job's settings hash there,
which is how a completed job is recognised (:func:`completed`).

Add an output format: a module in this folder with a :class:`FrameWriter` subclass that lists its
``extensions``, and its line in ``dftl_warp/output/__init__.py`` (:func:`register_writer`).
"""

from __future__ import annotations

import os
from pathlib import Path

from ..errors import UserError
from .paths import check_writable


class FrameWriter:
    """The interface every output format implements (see the module docstring)."""

    #: file extensions (lower case, with the dot) this writer writes; the first is its default
    extensions: tuple[str, ...] = ()
    #: whether :meth:`reopen` can continue a partial file (batch resume); else a batch job that
    #: was interrupted starts over
    resumable: bool = False
    #: optional keywords :meth:`create` takes beyond the interface's (``velocities=False``: write
    #: no velocities; a writer without it cannot honour ``--no-velocities``)
    create_options: tuple[str, ...] = ()

    # -- construction ---------------------------------------------------------------------------

    @classmethod
    def create(cls, output, scene, *, frames: tuple[int, int] | None = None, keep_partial: bool = False):
        raise NotImplementedError

    @classmethod
    def reopen(cls, output, scene, *, keep_partial: bool = True):
        """Continue the partial file of ``output`` (:meth:`partial_path`) left by an earlier run."""
        raise UserError(f"{output}: {cls.__name__} cannot continue a partial output")

    @classmethod
    def partial_path(cls, output) -> Path:
        """The fixed file a resumable writer of ``output`` streams into before :meth:`commit`."""
        output = Path(output)
        return output.with_name(f".{output.name}.dftl-partial{output.suffix}")

    @classmethod
    def check_path(cls, output, input_path=None) -> Path:
        """Refuse an ``output`` that cannot be written, before any work is done."""
        output = Path(os.fspath(output))
        check_writable(output)
        if input_path is not None and output.exists() and Path(input_path).exists():
            if os.path.samefile(output, input_path):
                raise UserError(f"{output}: the output would overwrite the input")
        return output

    # -- writing --------------------------------------------------------------------------------

    def write_frame(self, time_code: float, samples) -> None:
        raise NotImplementedError

    def write_qc(self, time_code: float, qc: dict) -> None:
        """Store the frame's QC (prim path -> {metric: value}, :mod:`dftl_warp.output.qc`) with the
        frame. A format that has no place for it ignores it (this default)."""

    def flush(self) -> None:
        """Make the frames written so far durable in the partial file."""

    @property
    def written_time_codes(self) -> list[float]:
        """Time codes with a complete sample for every prim (in the partial file)."""
        raise NotImplementedError

    @property
    def is_open(self) -> bool:
        """False once committed or aborted."""
        raise NotImplementedError

    # -- records --------------------------------------------------------------------------------

    def set_record(self, name: str, record: dict) -> None:
        """Store ``record`` (str keys; str, int, float values) in the output under ``name``."""
        raise NotImplementedError

    def record(self, name: str) -> dict | None:
        """The record ``name`` of this (reopened) writer's partial file, or None."""
        raise NotImplementedError

    @classmethod
    def read_record(cls, path, name: str) -> dict | None:
        """The record ``name`` of the finished output ``path``, or None (no file, unreadable, none)."""
        return None

    # -- finishing ------------------------------------------------------------------------------

    def commit(self) -> Path:
        raise NotImplementedError

    def abort(self) -> None:
        raise NotImplementedError

    def __enter__(self):
        return self

    def __exit__(self, exc_type, exc, tb):
        if exc_type is not None and self.is_open:
            self.abort()
        return False


#: extension (".usdc") -> writer class, in registration order
WRITERS: dict[str, type] = {}


def register_writer(cls):
    """Make ``cls`` (a :class:`FrameWriter`) the writer of its ``extensions``; returns it."""
    if not (isinstance(cls, type) and issubclass(cls, FrameWriter)) or not cls.extensions:
        raise ValueError(f"{cls!r} is not a FrameWriter with extensions")
    for ext in cls.extensions:
        ext = ext.lower()
        if not ext.startswith(".") or WRITERS.get(ext, cls) is not cls:
            raise ValueError(f"output extension {ext!r} is malformed or taken")
    for ext in cls.extensions:
        WRITERS[ext.lower()] = cls
    return cls


def output_extensions() -> tuple[str, ...]:
    """Every registered output extension, in registration order."""
    return tuple(WRITERS)


def extensions_text() -> str:
    """``.usdc, .usda, .usd`` (the registered extensions, for messages)."""
    return ", ".join(WRITERS)


def writer_for(output) -> type:
    """The writer class of ``output``'s extension; a UserError naming the choices otherwise (and
    for an empty path, which Path reads as the current folder)."""
    if not os.fspath(output).strip():
        raise UserError(f"output {os.fspath(output)!r}: empty path: give the file to write ({extensions_text()})")
    output = Path(os.fspath(output))
    cls = WRITERS.get(output.suffix.lower())
    if cls is None:
        default = next(iter(WRITERS), "")
        raise UserError(f"{output}: output must end in {extensions_text()} ({default} is the default)")
    return cls


def check_output_path(output, input_path=None) -> Path:
    """Refuse outputs that cannot be written (unknown extension, unwritable place, the input)."""
    return writer_for(output).check_path(output, input_path)


def ensure_folder(output) -> Path:
    """Create the folder of ``output`` if it is missing (a UserError when it cannot be)."""
    folder = Path(os.fspath(output)).parent
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise UserError(f"{output}: cannot create folder {folder}: {exc.strerror or exc}") from None
    return folder


def completed(output, name: str, key: str) -> bool:
    """Whether ``output`` exists and its record ``name`` holds ``settings_hash == key``."""
    output = Path(os.fspath(output))
    cls = WRITERS.get(output.suffix.lower())
    if cls is None or not output.is_file():
        return False
    record = cls.read_record(output, name)
    return isinstance(record, dict) and record.get("settings_hash") == key
