"""Checks of values that must fit the model's float precision, shared by every layer: the USD
reader (points, widths, collider sizes), the Model (points, origin, root targets), the solvers
(gravity), the features (collider sizes, mesh points) and the renderer. Plain numpy.

- :data:`FLOAT32_MAX`: the largest float32 (USD's point3f and float widths, a float32 model);
- :data:`MAX_LENGTH`: the largest length whose square fits float32;
- :func:`check_lengths`: the first value beyond :data:`MAX_LENGTH`, named in one line.
"""

from __future__ import annotations

import numpy as np

from .errors import UserError

#: the largest float32, USD's point3f and float widths
FLOAT32_MAX = float(np.finfo(np.float32).max)

#: the largest length (stage units) whose square fits float32: distances and depths past it
#: overflow to inf in the float32 collider and clean-start arithmetic
MAX_LENGTH = float(np.sqrt(FLOAT32_MAX))


def check_lengths(values, name: str, where: str, indexed: bool = True, world: str = "",
                  error: type = UserError) -> None:
    """UserError (or ``error``: the Python API's ValueError) naming the first value (a row of a
    (K, n) array; ``name[i]`` when ``indexed``) beyond :data:`MAX_LENGTH`: one that does not fit
    float32 at all, or whose square does not. ``world`` says how the value was reached (e.g. " in
    world space"); an empty ``where`` leaves the message's prefix out."""
    rows = np.abs(np.asarray(values, dtype=np.float64).reshape(len(np.atleast_1d(values)), -1))
    big = np.flatnonzero(~(rows.max(axis=1, initial=0.0) <= MAX_LENGTH))
    if not big.size:
        return
    i = int(big[0])
    row = np.asarray(values, dtype=np.float64).reshape(rows.shape)[i]
    shown = f"{row[0]:g}" if row.size == 1 else "(" + ", ".join(f"{v:g}" for v in row) + ")"
    label = f"{name}[{i}]" if indexed else name
    if rows[i].max() > FLOAT32_MAX:
        why = f"does not fit float32 (at most {FLOAT32_MAX:.4g})"
    else:
        why = f"is too large: its square does not fit float32 (lengths at most {MAX_LENGTH:.4g})"
    raise error(f"{where + ': ' if where else ''}{label} = {shown}{world} {why}: is the unit right?")
