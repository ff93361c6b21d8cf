"""Progress and messages on stderr: a tqdm bar on a terminal, plain lines in a log.

A bar redraws itself with carriage returns, which fill a farm's log file with one long line.
When the stream is not a terminal, :class:`LineProgress` prints one line per 10 % of the work
or per minute, whichever comes first. ``simulate`` and ``batch`` (its per-job progress when not
on a terminal) share it.
"""

from __future__ import annotations

import os
import sys
import time

#: what every line the program writes on stderr starts with (warnings: ``dftl-warp: warning: ``)
PREFIX = "dftl-warp: "


def stderr_line(text: str, warning: bool = False) -> str:
    """``text`` as a line of stderr: ``dftl-warp: TEXT`` (``dftl-warp: warning: TEXT`` for a
    warning), unless it already starts with ``dftl-warp: ``."""
    if text.startswith(PREFIX):
        return text
    return f"{PREFIX}{'warning: ' if warning else ''}{text}"


def is_plain_note(text: str) -> bool:
    """Whether a line of the clean start (``Summary.start_notes``) only reports what was asked for
    (a preroll that settled), not something moved, approximated or skipped: a note, not a warning
    (simulate's and batch's rule)."""
    return text == "preroll: none" or (text.startswith("preroll: ") and ", settled:" in text)


def start_line(text: str) -> str:
    """A clean-start line as printed: ``dftl-warp: preroll: ...`` or ``dftl-warp: warning: ...``."""
    return stderr_line(text, warning=not is_plain_note(text))


class LineProgress:
    """``update(n)`` / ``write(text)`` / ``close()`` like tqdm, printing plain lines:
    ``dftl-warp: simulating: 48/96 frames (50%), 3.1 s``."""

    def __init__(self, total: int, desc: str = "", unit: str = "frames", file=None, *,
                 every_share: float = 0.1, every_seconds: float = 60.0, clock=time.monotonic):
        self.total = max(int(total), 0)
        self.desc = desc
        self.unit = unit
        self.file = file if file is not None else sys.stderr
        self.every_share = every_share
        self.every_seconds = every_seconds
        self.clock = clock
        self.n = 0
        self._start = self._last_time = clock()
        self._last_n = 0
        self._closed = False

    def line(self) -> str:
        label = f"{self.desc}: " if self.desc else ""
        share = f" ({100 * self.n // self.total}%)" if self.total else ""
        return f"dftl-warp: {label}{self.n}/{self.total} {self.unit}{share}, {self.clock() - self._start:.1f} s"

    def update(self, n: int = 1) -> None:
        self.set(self.n + n)

    def set(self, n: int) -> None:
        """Progress is ``n`` units done (a line when 10 % more is done or a minute has passed)."""
        self.n = int(n)
        now = self.clock()
        step = max(1, int(self.total * self.every_share)) if self.total else 1
        due = self.n - self._last_n >= step or now - self._last_time >= self.every_seconds
        if self.total and self.n >= self.total and self._last_n < self.total:
            due = True
        if due and self.n != self._last_n:
            self._last_n, self._last_time = self.n, now
            self.write(self.line())

    def write(self, text: str, file=None) -> None:
        print(text, file=file or self.file, flush=True)

    def close(self) -> None:
        self._closed = True


def progress_bar(total: int, desc: str = "", unit: str = "frame", file=None):
    """A tqdm bar on ``file`` (default stderr) when it is a terminal (not ``TERM=dumb``), else a
    :class:`LineProgress`."""
    file = file if file is not None else sys.stderr
    try:
        tty = file.isatty()
    except (AttributeError, ValueError):
        tty = False
    if tty and os.environ.get("TERM") != "dumb":   # a dumb terminal cannot redraw a bar: lines
        from tqdm import tqdm

        return tqdm(total=total, unit=unit, desc=desc, leave=True, dynamic_ncols=True, file=file)
    return LineProgress(total, desc, unit + "s", file)
