"""The output lock: one dftl-warp process writes an output at a time (``simulate`` and ``batch``).

The lock is ``flock`` on a hidden sibling file, ``.NAME.dftl-lock`` next to ``NAME``
(:func:`lock_path`), created when taken and removed when released. ``flock`` locks die with
their process, so a killed run never leaves a stale lock; the file it leaves is simply locked
again by the next run.
"""

from __future__ import annotations

import contextlib
import os
import time
from pathlib import Path

from ..errors import UserError


def lock_path(output) -> Path:
    """The lock file of ``output``."""
    output = Path(os.fspath(output))
    return output.with_name(f".{output.name}.dftl-lock")


@contextlib.contextmanager
def output_lock(path, wait: float = 0.0, message: str | None = None):
    """Exclusive lock on the lock file ``path`` (created, removed on exit) so that two processes
    never work on the same output; waits up to ``wait`` s for a holder (e.g. a process being
    killed), then raises :class:`UserError` with ``message`` (default: the path and
    "another dftl-warp process is working on this output")."""
    try:
        import fcntl
    except ImportError:  # pragma: no cover - not POSIX: no locking
        yield
        return
    path = Path(path)
    deadline = time.monotonic() + wait
    while True:
        try:
            fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
        except OSError as exc:
            raise UserError(_cannot_create(path, exc)) from None
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            os.close(fd)
            if time.monotonic() >= deadline:
                raise UserError(message or f"{path}: another dftl-warp process is working on this output") from None
            time.sleep(0.1)
            continue
        try:  # the file we locked may have been removed by its last holder: lock the new one
            same = os.fstat(fd).st_ino == os.stat(path).st_ino
        except FileNotFoundError:
            same = False
        if same:
            break
        os.close(fd)
    try:
        yield
    finally:
        with contextlib.suppress(FileNotFoundError):
            os.remove(path)
        os.close(fd)


def _cannot_create(path: Path, exc: OSError) -> str:
    """The one line for a lock file that cannot be created: it names the output the user gave
    (``OUT`` of ``.OUT.dftl-lock``), not the hidden lock file."""
    reason = exc.strerror or str(exc)
    reason = reason[:1].lower() + reason[1:]
    name = path.name
    if name.startswith(".") and name.endswith(".dftl-lock") and len(name) > len("..dftl-lock"):
        output = path.with_name(name[1:-len(".dftl-lock")])
        return f"{output}: cannot write: cannot create a file in folder {path.parent} ({reason})"
    return f"{path}: cannot create the lock file: {reason}"
