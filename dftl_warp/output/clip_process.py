"""A value-clips writer process (:mod:`.clip_pool` starts it; docs/caches.md, "Value clips").

The process authors the chunks its parent hands it, one crate layer per chunk, frame by frame as
the frames arrive: a frame's samples lie in a slot of the shared frame memory (a file descriptor
inherited from the parent), the message names the slot, and the slot is given back as soon as its
arrays are copied into ``Vt`` arrays. When the chunk's last frame is in, the parent asks for the
save: the layer is saved under a hidden name and renamed into place (whole or absent), and the
outcome goes back (``None`` or the error). Processes, not threads: authoring and
``Sdf.Layer.Save`` hold Python's interpreter lock for most of their time, so threads take turns.

Messages, parent to process (pickled over a Unix socket): ``("setup", config)`` once, followed by
the shared memory's file descriptor (``socket.send_fds``), then ``("frame", chunk, path, time,
slot, has_velocities)``, ``("save", chunk)``, ``("stop",)``. Process to parent: ``("ready",)``,
``("free", slot)``, ``("saved", chunk, error)`` with ``error`` None, ``("os", errno, strerror)`` or
``("usd", message)``. With ``config["fsync"]`` a saved layer is fsync'd (by a second thread, while
the next chunk is authored) before it is renamed into place and its save answered.

The process imports USD as it starts, before its set-up arrives (:func:`.clip_pool.start_early`).
It ends at ``("stop",)``, when its parent's socket closes, and (Linux) when its parent dies
(``PR_SET_PDEATHSIG``), so a killed run leaves no writer behind.
"""

from __future__ import annotations

import contextlib
import mmap
import os
import socket
import sys
import threading
from concurrent.futures import ThreadPoolExecutor
from multiprocessing.connection import Connection
from pathlib import Path

import numpy as np

from ..durable import fsync_file
from .vtarrays import vec3f_array


def _die_with_parent(parent: int) -> None:
    """Linux: SIGKILL this process when its parent dies (else the closed socket ends it)."""
    if not sys.platform.startswith("linux"):
        return
    import ctypes
    import signal

    with contextlib.suppress(OSError, AttributeError):
        ctypes.CDLL(None, use_errno=True).prctl(1, int(signal.SIGKILL), 0, 0, 0)  # PR_SET_PDEATHSIG
    if os.getppid() != parent:  # the parent died before the prctl
        os._exit(1)


class _Chunk:
    """One clip layer being authored: ``Sdf`` specs made, samples added frame by frame."""

    def __init__(self, path: str, targets, velocities: bool):
        from pxr import Sdf

        self.final = Path(path)
        self.path = self.final.with_name("." + self.final.name + ".tmp.usdc")
        self.layer = None
        with contextlib.suppress(FileNotFoundError):
            self.path.unlink()
        self.layer = Sdf.Layer.CreateNew(str(self.path))
        self.specs = []
        with Sdf.ChangeBlock():
            for prim_path, _ in targets:
                prim = Sdf.CreatePrimInLayer(self.layer, prim_path)
                prim.specifier = Sdf.SpecifierOver
                names = [("points", Sdf.ValueTypeNames.Point3fArray), ("extent", Sdf.ValueTypeNames.Float3Array)]
                if velocities:
                    names.append(("velocities", Sdf.ValueTypeNames.Vector3fArray))
                for name, kind in names:
                    Sdf.AttributeSpec(prim, name, kind)
                path_ = Sdf.Path(prim_path)
                self.specs.append(tuple(path_.AppendProperty(n) for n in ("points", "extent", "velocities")))

    def add(self, time: float, arrays, widths) -> None:
        """The samples at ``time``: ``arrays`` [(points, velocities or None)] per target."""
        from pxr import Sdf, UsdGeom

        with Sdf.ChangeBlock():
            for (p_path, e_path, v_path), (p, v), w in zip(self.specs, arrays, widths):
                pts = vec3f_array(p)   # one memory copy (FromNumpy converts float by float)
                self.layer.SetTimeSample(p_path, time, pts)
                if w is not None:
                    extent = UsdGeom.Curves.ComputeExtent(pts, w)
                else:
                    extent = UsdGeom.PointBased.ComputeExtent(pts)
                self.layer.SetTimeSample(e_path, time, extent)
                if v is not None:
                    self.layer.SetTimeSample(v_path, time, vec3f_array(v))

    def save(self) -> None:
        """Save the layer under its hidden name (then :meth:`finish`)."""
        if not self.layer.Save():
            raise OSError(0, "USD did not save the layer")
        self.layer = None  # its arrays go now

    def finish(self, fsync: bool) -> None:
        """Make the saved layer durable (``fsync``) and rename it into place: whole or absent under
        its own name (batch resume keeps whole chunks)."""
        if fsync:
            fsync_file(self.path)
        os.replace(self.path, self.final)   # into the partial folder: the commit syncs it (durable.replace_folder)

    def drop(self) -> None:
        self.layer = None
        with contextlib.suppress(OSError):
            self.path.unlink()


def _error(exc: BaseException):
    from pxr import Tf

    if isinstance(exc, OSError):
        return ("os", exc.errno or 0, exc.strerror or str(exc))
    if isinstance(exc, Tf.ErrorException):
        from ..usd.stage import tf_message

        return ("usd", tf_message(exc))
    return ("usd", f"{type(exc).__name__}: {exc}")


def serve(sock: socket.socket) -> None:
    """Author chunks as the parent says over ``sock`` until ``("stop",)`` or the socket closes."""
    from pxr import Sdf, Tf, UsdGeom, Vt  # noqa: F401 - loaded now, while the parent sets up

    conn = Connection(os.dup(sock.fileno()))
    try:
        kind, config = conn.recv()
        _, (memory_fd,), _, _ = socket.recv_fds(sock, 1, 1)
    except (EOFError, OSError, ValueError):  # the parent ended before handing over any work
        return
    assert kind == "setup", kind
    from pxr import Work

    Work.SetConcurrencyLimit(config["threads"])  # the writers share the cores
    memory = mmap.mmap(memory_fd, config["bytes"], prot=mmap.PROT_READ)
    os.close(memory_fd)  # the mapping stays
    # the mapping is rounded up to a whole page: the slots are its first ``slots * floats`` floats
    slots = np.frombuffer(memory, np.float32, count=config["slots"] * config["floats"])
    slots = slots.reshape(config["slots"], config["floats"])
    targets = config["targets"]
    widths = [None if w is None else Vt.FloatArray.FromNumpy(np.asarray(w, np.float32)) for _, w in targets]
    layout = config["layout"]  # per target: (points offset, velocities offset or None, count), in floats
    chunks: dict[int, _Chunk] = {}
    failed: dict[int, tuple] = {}
    lock = threading.Lock()  # the answers come from this thread and the finishing one
    finishing = ThreadPoolExecutor(1, thread_name_prefix="dftl-clip-fsync")  # the disk works while we author

    def answer(message) -> None:
        with lock:
            conn.send(message)

    def finish(index: int, chunk: _Chunk) -> None:
        try:
            chunk.finish(config["fsync"])
        except Exception as exc:
            chunk.drop()
            answer(("saved", index, _error(exc)))
        else:
            answer(("saved", index, None))

    answer(("ready",))
    try:
        while True:
            message = conn.recv()
            if message[0] == "frame":
                _, index, path, time, slot, has_v = message
                try:
                    if index not in failed:
                        if index not in chunks:
                            chunks[index] = _Chunk(path, targets, config["velocities"])
                        row = slots[slot]
                        arrays = [(row[p:p + 3 * n].reshape(n, 3),
                                   row[v:v + 3 * n].reshape(n, 3) if v is not None and h else None)
                                  for (p, v, n), h in zip(layout, has_v)]
                        chunks[index].add(time, arrays, widths)
                        del arrays, row
                except Exception as exc:  # reported at the chunk's save
                    failed[index] = _error(exc)
                    chunk = chunks.pop(index, None)
                    if chunk is not None:
                        chunk.drop()
                answer(("free", slot))
            elif message[0] == "save":
                index = message[1]
                error = failed.pop(index, None)
                chunk = chunks.pop(index, None)
                if error is None and chunk is not None:
                    try:
                        chunk.save()
                    except Exception as exc:
                        error = _error(exc)
                        chunk.drop()
                    else:
                        finishing.submit(finish, index, chunk)
                        continue
                answer(("saved", index, error))
            elif message[0] == "stop":
                finishing.shutdown(wait=True)
                return
    except (EOFError, OSError):  # the parent closed the socket: its run is over
        return
    finally:
        finishing.shutdown(wait=True)
        for chunk in chunks.values():
            chunk.drop()
        del slots
        with contextlib.suppress(BufferError):
            memory.close()


def main(argv) -> None:
    """``python -c BOOT ROOT SOCKET_FD PARENT_PID`` (:mod:`.clip_pool`)."""
    fd, parent = (int(a) for a in argv[:2])
    _die_with_parent(parent)
    with socket.socket(fileno=fd) as sock:
        serve(sock)
