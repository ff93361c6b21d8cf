"""numpy -> ``Vt.Vec3fArray`` at the speed of a memory copy, for the per-frame time samples.

``Vt.Vec3fArray.FromBuffer`` / ``FromNumpy`` convert element by element through a generic strided
loop with a conversion call per float: about 25 ns a point, 160 ms a frame for the points and
velocities of 200k strands x 32 points, most of the writer's time (docs/benchmarks-usd.md).
:func:`vec3f_array` makes a new array of the right length and fills its storage with one numpy
copy (converting float64 to float32 on the way, rounding to nearest as ``FromBuffer`` does).

Vt exports an array's storage only read-only (its arrays are shared copy-on-write). The array
written here is new and referenced by nothing else, so filling its storage in place is the same as
constructing it with those values; it is handed out only once filled. Where a usd-core exports a
copy instead of its storage (the fill would not show), a check on the first call notices it and
every call falls back to ``FromBuffer``: the values are the same either way.
"""

from __future__ import annotations

import ctypes

import numpy as np

#: None: not checked yet; True: the storage is filled in place; False: FromBuffer
_in_place: bool | None = None


def vec3f_array(rows):
    """A ``Vt.Vec3fArray`` holding ``rows`` ((N, 3) or flat 3N, float32 or float64: the same values
    ``Vt.Vec3fArray.FromBuffer`` gives, float64 rounded to the nearest float32)."""
    from pxr import Vt

    global _in_place
    a = np.asarray(rows)
    if a.dtype not in (np.float32, np.float64):
        a = a.astype(np.float64)
    a = a.reshape(-1, 3)
    if _in_place is None:
        _in_place = _fill_shows()
    if not _in_place or a.shape[0] == 0:
        return Vt.Vec3fArray.FromBuffer(np.ascontiguousarray(a))
    out = Vt.Vec3fArray(a.shape[0])
    with np.errstate(over="ignore", invalid="ignore"):  # as FromBuffer: out of range -> inf, NaN stays NaN
        np.copyto(_storage(out), a, casting="unsafe")
    return out


def _storage(array) -> np.ndarray:
    """A writable (N, 3) float32 view of the storage of the new, unshared Vt.Vec3fArray ``array``."""
    n = len(array)
    address = np.asarray(array).__array_interface__["data"][0]  # the buffer export is released again here
    return np.ctypeslib.as_array((ctypes.c_float * (3 * n)).from_address(address)).reshape(n, 3)


def _fill_shows() -> bool:
    """Whether filling :func:`_storage` changes the array (its buffer export is its storage)."""
    from pxr import Gf, Vt

    probe = Vt.Vec3fArray(2)
    _storage(probe)[:] = ((1.0, 2.0, 3.0), (4.0, 5.0, 6.0))
    return probe[1] == Gf.Vec3f(4.0, 5.0, 6.0) and probe[0] == Gf.Vec3f(1.0, 2.0, 3.0)
