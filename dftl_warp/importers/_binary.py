"""Small helpers shared by the binary readers: bounded, offset-aware reads that raise
:class:`~dftl_warp.errors.UserError` (``"FILE: offset N: ..."``) instead of numpy/struct errors."""

from __future__ import annotations

import os
import struct

import numpy as np

from ..errors import UserError, plural


def read_bytes(path) -> bytes:
    path = os.fspath(path)
    if not os.path.exists(path):
        raise UserError(f"{path}: no such file")
    if os.path.isdir(path):
        raise UserError(f"{path}: is a directory")
    try:
        with open(path, "rb") as f:
            return f.read()
    except OSError as exc:
        raise UserError(f"{path}: cannot read: {exc.strerror or exc}") from None


class Buffer:
    """A byte string read with explicit offsets; every failure names the file and offset."""

    def __init__(self, data: bytes, path: str):
        self.data = data
        self.path = os.fspath(path)
        self.size = len(data)

    def error(self, offset: int, what: str) -> UserError:
        return UserError(f"{self.path}: offset {offset}: {what}")

    def need(self, offset: int, nbytes: int, what: str) -> None:
        if offset < 0 or nbytes < 0 or offset + nbytes > self.size:
            have = max(self.size - offset, 0)
            raise self.error(offset, f"truncated: {what} needs {nbytes} bytes, the file has {have} left "
                                     f"(file size {self.size})")

    def unpack(self, fmt: str, offset: int, what: str) -> tuple:
        n = struct.calcsize(fmt)
        self.need(offset, n, what)
        return struct.unpack_from(fmt, self.data, offset)

    def array(self, dtype, count: int, offset: int, what: str) -> np.ndarray:
        dtype = np.dtype(dtype)
        self.need(offset, count * dtype.itemsize, what)
        return np.frombuffer(self.data, dtype=dtype, count=count, offset=offset)


def check_finite(path: str, points: np.ndarray, counts: np.ndarray, what: str = "point") -> None:
    """Raise ``FILE: strand K: ...`` for the first strand with a NaN or infinite coordinate."""
    bad = ~np.isfinite(points).all(axis=1)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        starts = np.concatenate([[0], np.cumsum(counts)])
        k = int(np.searchsorted(starts, i, side="right") - 1)
        j = i - int(starts[k])
        p = ", ".join(f"{v:g}" for v in points[i])
        raise UserError(f"{path}: strand {k}: {what} {j} = ({p}) is not finite "
                        f"(--drop-nonfinite drops such strands)")


def drop_short_strands(path: str, points: np.ndarray, counts: np.ndarray, widths, warnings: list):
    """Drop strands with fewer than 2 vertices (no segment: not a curve), with one warning giving
    their count, the same for every format. Returns (points, counts, widths)."""
    keep = counts >= 2
    if keep.all():
        return points, counts, widths
    warnings.append(f"{path}: dropped {int((~keep).sum())} of {plural(counts.size, 'strand')} with fewer than 2 "
                    "vertices")
    mask = np.repeat(keep, counts)
    return points[mask], counts[keep], None if widths is None else widths[mask]
