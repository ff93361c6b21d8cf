"""The writer processes of value clips (:mod:`.clips`; docs/caches.md, "Value clips").

:class:`ClipWriterPool` starts :func:`writer_count` processes (:mod:`.clip_process`) next to the
frame loop (or takes those :func:`start_early` started). A frame goes to them through shared
memory, not a pickle: :meth:`ClipWriterPool.put_frame` copies its samples into a free slot of one
shared frame memory (``memfd`` on Linux; the copy releases the interpreter lock) and sends the
slot's number to the process that authors the frame's chunk, which copies the slot into ``Vt``
arrays and gives it back. A chunk's layer is thus authored
while its frames are simulated, and only its save is left when its last frame arrives
(:meth:`ClipWriterPool.save`). Each chunk goes to the process with the fewest unsaved chunks.

The slots bound the frames in flight (:func:`slot_count`): when every slot is taken the frame loop
waits for the writers (backpressure). A writer process that ends unexpectedly is one
:class:`~dftl_warp.errors.UserError` line; :meth:`ClipWriterPool.kill` ends the processes (only
those it started) before a failed run's partial files are removed.
"""

from __future__ import annotations

import atexit
import contextlib
import mmap
import os
import socket
import subprocess
import sys
import tempfile
import threading
from multiprocessing.connection import Connection, wait
from pathlib import Path

import numpy as np

from ..errors import UserError

#: at most this many writer processes (8 independent crate writers reached 0.87 GB/s on the H200
#: machine, docs/caches.md)
MAX_WRITERS = 8
#: the frames in flight may take at most this share of the machine's memory
MEMORY_SHARE = 1 / 8

#: glibc malloc in the writer processes: a chunk's arrays come from (and go back to) the heap, not
#: fresh mappings, so the next chunk reuses its pages instead of faulting in new ones
MALLOC = {"MALLOC_MMAP_THRESHOLD_": str(1 << 30), "MALLOC_TRIM_THRESHOLD_": str(1 << 30)}

#: the writer process's command: ``python -c BOOT ROOT SOCKET_FD PARENT_PID``; ROOT (the
#: folder holding this ``dftl_warp``) goes first on ``sys.path``, so the process runs this copy
BOOT = ("import sys; sys.path.insert(0, sys.argv[1]); "
        "from dftl_warp.output.clip_process import main; main(sys.argv[2:])")


def cores() -> int:
    """The CPU cores this process may run on."""
    with contextlib.suppress(AttributeError, OSError):
        return len(os.sched_getaffinity(0))
    return os.cpu_count() or 1


def writer_count(available: int | None = None) -> int:
    """Writer processes for ``available`` cores (default: :func:`cores`): one per core, at most
    :data:`MAX_WRITERS`. The frame loop's share of the work is small (its copy into shared memory:
    ~0.3 CPU s per written GB against ~2.2 in the writers; docs/caches.md), and on 2 cores two
    writers wrote 1.4x one."""
    available = cores() if available is None else int(available)
    return max(1, min(MAX_WRITERS, available))


def slot_count(writers: int, frame_bytes: int) -> int:
    """Frame slots: two per writer and two for the frame loop, within :data:`MEMORY_SHARE` of the
    memory (at least 2)."""
    try:
        memory = os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (AttributeError, ValueError, OSError):
        memory = 8 << 30
    return max(2, min(2 * writers + 2, int(memory * MEMORY_SHARE) // max(1, frame_bytes)))


def _shared_file() -> int:
    """A file descriptor of memory to share with the writer processes: an anonymous ``memfd``
    (Linux; not bounded by the size of /dev/shm), else an unlinked temporary file."""
    if hasattr(os, "memfd_create"):
        return os.memfd_create("dftl-clip-frames")
    handle, name = tempfile.mkstemp(prefix="dftl-clip-frames-", dir="/dev/shm" if os.path.isdir("/dev/shm") else None)
    os.unlink(name)
    return handle


class _Worker:
    """One writer process and the socket to it (pickled messages both ways; the shared frame
    memory's descriptor goes over it with :meth:`setup`)."""

    def __init__(self):
        mine, theirs = socket.socketpair()
        root = str(Path(__file__).resolve().parents[2])
        try:
            self.process = subprocess.Popen([sys.executable, "-c", BOOT, root, str(theirs.fileno()), str(os.getpid())],
                                            pass_fds=(theirs.fileno(),), stdin=subprocess.DEVNULL,
                                            stdout=subprocess.DEVNULL, env={**MALLOC, **os.environ},
                                            start_new_session=True)   # a terminal's Ctrl-C is the parent's
        except BaseException:
            mine.close()
            raise
        finally:
            theirs.close()
        self.socket = mine
        self.conn = Connection(os.dup(mine.fileno()))

    def setup(self, config: dict, memory_fd: int) -> None:
        self.conn.send(("setup", config))
        socket.send_fds(self.socket, [b"m"], [memory_fd])

    def send(self, message) -> None:
        self.conn.send(message)

    def close(self) -> None:
        with contextlib.suppress(OSError):
            self.conn.close()
        self.socket.close()

    def kill(self) -> None:
        with contextlib.suppress(OSError):
            self.process.kill()
        self.process.wait()
        self.close()


#: writer processes started ahead of their pool (:func:`start_early`)
_EARLY: list[_Worker] = []


def start_early(writers: int | None = None) -> None:
    """Start the writer processes now, for the next :class:`ClipWriterPool` of this process to
    take: their start (mostly importing USD) then overlaps the simulation's set-up instead of the
    first frames. Processes nobody takes end with this process."""
    wanted = writer_count() if writers is None else max(1, int(writers))
    while len(_EARLY) < wanted:
        _EARLY.append(_Worker())


@atexit.register
def _end_early() -> None:
    while _EARLY:
        _EARLY.pop().kill()


class ClipWriterPool:
    """Writer processes fed through shared frame slots (see the module docstring).

    ``targets``: [(prim path, widths array or None)] per written prim; ``counts``: its points per
    frame; ``velocities``: whether the layers hold velocities; ``fsync``: each layer is on the disk
    (``os.fsync``) before its save is answered; ``name``: the output (messages)."""

    def __init__(self, targets, counts, velocities: bool, *, writers: int | None = None, fsync: bool = False,
                 name: str = "clips"):
        self.name = name
        self.writers = writer_count() if writers is None else max(1, int(writers))
        self.layout, floats = [], 0
        for n in counts:
            n = int(n)
            self.layout.append((floats, floats + 3 * n if velocities else None, n))
            floats += 3 * n * (2 if velocities else 1)
        self.slots = slot_count(self.writers, 4 * floats)
        size = max(mmap.PAGESIZE, 4 * floats * self.slots)
        fd = _shared_file()
        try:
            os.ftruncate(fd, size)
            self._memory = mmap.mmap(fd, size)
            config = {"bytes": size, "slots": self.slots, "floats": floats, "layout": self.layout,
                      "threads": max(2, cores() // self.writers),  # USD's own (Work) threads per process
                      "velocities": bool(velocities), "fsync": bool(fsync),
                      "targets": [(str(p), None if w is None else np.asarray(w, np.float32)) for p, w in targets]}
            self.workers: list[_Worker] = []
            try:
                while len(self.workers) < self.writers:
                    worker = _EARLY.pop(0) if _EARLY else _Worker()
                    try:
                        worker.setup(config, fd)
                    except OSError:  # an early process that has ended meanwhile: a new one
                        worker.kill()
                        worker = _Worker()
                        self.workers.append(worker)
                        worker.setup(config, fd)
                    else:
                        self.workers.append(worker)
            except BaseException:
                self.kill()
                raise
        finally:
            os.close(fd)  # the mappings stay
        self.frames = np.frombuffer(self._memory, np.float32, count=floats * self.slots).reshape(self.slots, floats)
        self._free = list(range(self.slots))
        self._owner: dict[int, int] = {}      # chunk -> worker
        self._unsaved = [0] * self.writers    # chunks given to each worker and not yet saved
        self._results: dict[int, object] = {}  # chunk -> None or the error the worker reported
        self._turn = 0

    # -- the frame loop's side ------------------------------------------------------------------

    def put_frame(self, chunk: int, path, time: float, samples) -> None:
        """Copy ``samples`` ([(points, velocities or None)] per prim) into a free slot and hand it
        to the process authoring ``chunk`` into ``path`` (chosen at the chunk's first frame)."""
        slot = self._slot()
        row = self.frames[slot]
        has_v = []
        for (p_at, v_at, n), (p, v) in zip(self.layout, samples):
            p = np.asarray(p).reshape(-1, 3)
            if len(p) != n:
                raise ValueError(f"{self.name}: a frame of {len(p)} points where the clips hold {n}")
            np.copyto(row[p_at:p_at + 3 * n].reshape(n, 3), p, casting="same_kind")
            has_v.append(v_at is not None and v is not None)
            if has_v[-1]:
                np.copyto(row[v_at:v_at + 3 * n].reshape(n, 3), np.asarray(v).reshape(n, 3), casting="same_kind")
        worker = self._owner.get(chunk)
        if worker is None:
            order = range(self._turn, self._turn + self.writers)
            worker = min((k % self.writers for k in order), key=lambda k: self._unsaved[k])
            self._turn = worker + 1
            self._owner[chunk] = worker
            self._unsaved[worker] += 1
        self._send(worker, ("frame", int(chunk), str(path), float(time), slot, tuple(has_v)))

    def save(self, chunk: int) -> None:
        """Ask for ``chunk``'s layer to be saved (its frames are all handed over)."""
        self._send(self._owner[chunk], ("save", int(chunk)))

    def done(self, chunk: int) -> bool:
        """Whether ``chunk``'s save has been answered (without waiting)."""
        self._poll(0)
        return chunk in self._results

    def result(self, chunk: int):
        """Wait for ``chunk``'s save: None, or the error its process reported (``("os", errno,
        strerror)`` or ``("usd", message)``)."""
        while chunk not in self._results:
            self._poll(None)
        return self._results.pop(chunk)

    # -- ending ---------------------------------------------------------------------------------

    def close(self) -> None:
        """Stop the processes (every save asked of them answered: their files are in place). Their
        exit (the interpreter's teardown) is waited for by a background thread, not by the commit."""
        processes = [w.process for w in self.workers]
        for w in self.workers:
            with contextlib.suppress(OSError):
                w.send(("stop",))
        self._release()
        threading.Thread(target=lambda: [p.wait() for p in processes], name="dftl-clip-reaper", daemon=True).start()

    def kill(self) -> None:
        """End the processes now (a failed or interrupted run), and wait for them."""
        for w in getattr(self, "workers", []):
            w.kill()
        self._release()

    def _release(self) -> None:
        for w in getattr(self, "workers", []):
            w.close()
        self.workers = []
        self.frames = None
        with contextlib.suppress(BufferError, AttributeError):
            self._memory.close()

    # -- messages -------------------------------------------------------------------------------

    def _send(self, worker: int, message) -> None:
        try:
            self.workers[worker].send(message)
        except OSError:
            self._ended(self.workers[worker])

    def _slot(self) -> int:
        self._poll(0)
        while not self._free:
            self._poll(None)
        return self._free.pop()

    def _poll(self, timeout) -> None:
        """Read every answer that has arrived (waiting up to ``timeout`` s for one; None: until one)."""
        if not self.workers:
            raise UserError(f"{self.name}: the clip writer processes have been stopped")
        by_conn = {w.conn: k for k, w in enumerate(self.workers)}
        for conn in wait(list(by_conn), timeout):
            worker = by_conn[conn]
            try:
                while conn.poll():
                    message = conn.recv()
                    if message[0] == "free":
                        self._free.append(message[1])
                    elif message[0] == "saved":
                        self._results[message[1]] = message[2]
                        self._unsaved[worker] -= 1
            except (EOFError, OSError):
                self._ended(self.workers[worker])

    def _ended(self, worker: _Worker):
        code = worker.process.poll()
        if code is None:
            with contextlib.suppress(subprocess.TimeoutExpired):
                code = worker.process.wait(5)
        raise UserError(f"{self.name}: a clip writer process ended unexpectedly (exit status {code})")
