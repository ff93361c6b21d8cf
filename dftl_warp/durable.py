"""Putting a finished file in place so that it survives a power loss: the one helper every output
goes through (a simulated layer, its value clips, a render's images, an imported stage, a batch's
checkpoints, the study's reports).

A file is written under a temporary name in its folder, then :func:`replace_file` makes it durable:
the file's data are flushed to the disk (``fsync``), it is renamed onto its final name (atomic:
the old file or the new one, never a mix), and the folder is flushed too, so the rename itself
survives. Without the first ``fsync`` a crash right after the rename can leave an empty or
truncated file under the final name (the rename reaches the disk before the data); without the
last one the old file may come back. Where the system cannot ``fsync`` a folder (Windows, some
network file systems) that step is skipped.

A foundation module: the standard library only.
"""

from __future__ import annotations

import contextlib
import os
from pathlib import Path


def fsync_file(path) -> None:
    """Flush the data of the file ``path`` to the disk."""
    fd = os.open(path, os.O_RDWR if os.name == "nt" else os.O_RDONLY)  # Windows flushes only writable handles
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def fsync_folder(folder) -> None:
    """Flush the folder ``folder``'s entries (renames, new files) to the disk, where the system can."""
    flags = os.O_RDONLY | getattr(os, "O_DIRECTORY", 0)
    try:
        fd = os.open(folder if str(folder) else ".", flags)
    except OSError:   # Windows cannot open a folder
        return
    try:
        with contextlib.suppress(OSError):   # EINVAL, EBADF: a file system without folder fsync
            os.fsync(fd)
    finally:
        os.close(fd)


def usual_permissions(path) -> None:
    """Give ``path`` 0666 less the umask (``tempfile.mkstemp`` makes private 0600 files)."""
    umask = os.umask(0)
    os.umask(umask)
    os.chmod(path, 0o666 & ~umask)


def replace_file(tmp, target, *, permissions: bool = False) -> None:
    """Move the finished file ``tmp`` onto ``target`` durably: fsync ``tmp``, rename it (atomic),
    fsync ``target``'s folder. ``permissions``: give it the usual permissions first
    (:func:`usual_permissions`). Raises OSError as ``os.replace`` does; ``tmp`` is left for the
    caller to remove then."""
    if permissions:
        usual_permissions(tmp)
    fsync_file(tmp)
    os.replace(tmp, target)
    fsync_folder(Path(os.fspath(target)).parent)


def sync_tree(folder) -> None:
    """Flush every file below ``folder`` and every folder (``folder`` included) to the disk: a
    folder of finished files about to be renamed into place (:func:`replace_folder`)."""
    for root, _dirs, files in os.walk(folder):
        for name in files:
            fsync_file(os.path.join(root, name))
        fsync_folder(root)


def replace_folder(tmp, target) -> None:
    """Move the finished folder ``tmp`` onto the free name ``target`` durably: every file and
    folder in it flushed (:func:`sync_tree`), renamed, ``target``'s parent flushed."""
    sync_tree(tmp)
    os.replace(tmp, target)
    fsync_folder(Path(os.fspath(target)).parent)


def write_file(path, write) -> None:
    """Write the file ``path`` whole or not at all: ``write(tmp)`` fills a temporary file in
    its folder (which must exist), then :func:`replace_file` puts it in place with the usual
    permissions. Any exception removes the temporary file and goes on up (OSError included)."""
    import tempfile

    path = Path(os.fspath(path))
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=path.suffix, dir=path.parent)
    os.close(fd)
    try:
        write(tmp)
        replace_file(tmp, path, permissions=True)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.remove(tmp)
        raise


def write_text(path, text: str) -> None:
    """Write ``text`` to ``path`` whole or not at all, durably (:func:`write_file`)."""
    write_file(path, lambda tmp: Path(tmp).write_text(text))
