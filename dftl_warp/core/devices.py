"""Warp initialisation for command-line use: quiet unless ``DFTL_WARP_VERBOSE`` is set."""

from __future__ import annotations

import contextlib
import os
import sys


def init_warp() -> None:
    """Initialise Warp once. Without ``DFTL_WARP_VERBOSE``, its banner and the native
    'no CUDA driver' notice of CPU-only machines are kept off the terminal."""
    import warp as wp

    if os.environ.get("DFTL_WARP_VERBOSE"):
        wp.init()
        return
    wp.config.log_level = wp.LOG_WARNING
    with _stderr_silenced():
        wp.init()


@contextlib.contextmanager
def _stderr_silenced():
    try:
        fd = sys.stderr.fileno()
    except (AttributeError, OSError, ValueError):
        yield
        return
    sys.stderr.flush()
    saved = os.dup(fd)
    with open(os.devnull, "w") as null:
        os.dup2(null.fileno(), fd)
        try:
            yield
        finally:
            os.dup2(saved, fd)
            os.close(saved)
