"""Authored values of standard schema attributes, read and shown for one-line messages.

- :func:`shown`: a value as a message shows it, in plain text: ``nan``, ``0.5``, ``(nan, -1, 0)``,
  ``[0.5, 0.5]``, ``'big'`` (never ``np.float64(nan)`` or ``Vt.FloatArray(2, (0.5, 0.5))``);
- :func:`number` and :func:`numbers3`: a schema attribute's value (``radius``, ``size``,
  ``physics:gravityMagnitude``, ``physics:gravityDirection`` ...) as a float, or 3 floats; a value that
  is not numeric (``string radius = "big"``, authored against the schema's type) raises
  :class:`~dftl_warp.errors.UserError` naming the file, the prim, the attribute and the value (the
  renderer's Camera and Lighting fields go through :func:`number` too, with its OptionError);
- :func:`boolean`: the same for a ``bool`` attribute (``physics:collisionEnabled``).
"""

from __future__ import annotations

import math

import numpy as np

from ..errors import UserError


def _scalar(value) -> str:
    if isinstance(value, (bool, np.bool_)):
        return "true" if value else "false"
    if isinstance(value, (int, np.integer)):
        return str(int(value))
    if isinstance(value, (float, np.floating)):
        return f"{float(value):g}"
    return repr(str(value)) if isinstance(value, str) else repr(value)


def shown(value) -> str:
    """``value`` as plain text for a message (numbers with ``%g``; a vector in parentheses, an
    array in brackets, its first 8 values)."""
    if value is None or isinstance(value, (str, bool, int, float, np.generic)):
        return "None" if value is None else _scalar(value)
    try:
        array = np.asarray(value)
    except Exception:   # noqa: BLE001 (a USD value numpy cannot hold: show its text)
        return repr(str(value))
    if array.dtype == object or array.dtype.kind not in "biuf":
        items = [str(v) for v in array.reshape(-1)[:8]] if array.ndim else [str(value)]
        return repr(items if array.ndim else items[0])
    if array.ndim == 0:
        return _scalar(array.item())
    flat = array.reshape(-1)
    rows = array.reshape(array.shape[0], -1) if array.ndim > 1 else None
    vector = type(value).__name__.startswith(("Vec", "Quat", "Matrix")) or isinstance(value, tuple)
    if vector and array.ndim == 1:
        return "(" + ", ".join(_scalar(v) for v in flat.tolist()) + ")"
    if rows is not None:
        items = ["(" + ", ".join(_scalar(v) for v in r.tolist()) + ")" for r in rows[:8]]
        more = len(rows) > 8
    else:
        items = [_scalar(v) for v in flat[:8].tolist()]
        more = flat.size > 8
    return "[" + ", ".join(items) + (", ..." if more else "") + "]"


def _numeric(value) -> bool:
    if isinstance(value, (bool, np.bool_)):
        return False
    return isinstance(value, (int, float, np.integer, np.floating))


def number(value, name: str, where: str = "", error: type = UserError, finite: bool = False) -> float:
    """``value`` (an attribute's value, e.g. ``radius``, or an API field, e.g. a camera's
    ``focal_length``) as a float, not yet checked for range; UserError (or ``error``) ``WHERE: name =
    VALUE: expected a number`` when it is not a number (a string, a bool, an array), and with
    ``finite`` ``... expected a finite number`` for NaN and infinities too. An empty ``where``
    leaves the message's prefix out (the renderer's API fields name themselves in ``name``)."""
    if not _numeric(value) or (finite and not math.isfinite(value)):
        raise error(f"{where + ': ' if where else ''}{name} = {shown(value)}: "
                    f"expected {'a finite number' if finite else 'a number'}")
    return float(value)


def numbers3(value, name: str, where: str) -> np.ndarray:
    """``value`` (a ``vector3f``, e.g. ``physics:gravityDirection``) as 3 floats (3,); UserError
    ``WHERE: name = VALUE: expected 3 numbers`` otherwise."""
    if isinstance(value, (str, bytes, bool, np.bool_)):
        raise UserError(f"{where}: {name} = {shown(value)}: expected 3 numbers")
    try:
        array = np.asarray(value)
    except Exception:   # noqa: BLE001 (a USD value numpy cannot hold)
        array = np.asarray(None, dtype=object)
    if array.dtype.kind not in "iuf" or array.size != 3:
        raise UserError(f"{where}: {name} = {shown(value)}: expected 3 numbers")
    return array.astype(np.float64).reshape(3)


def boolean(value, name: str, where: str) -> bool:
    """``value`` as a bool; UserError ``WHERE: name = VALUE: expected a bool`` otherwise."""
    if not isinstance(value, (bool, np.bool_)):
        raise UserError(f"{where}: {name} = {shown(value)}: expected a bool (true or false)")
    return bool(value)


def at_text(code) -> str:
    """"the default time" or "time T" for a Usd.TimeCode."""
    return "the default time" if code.IsDefault() else f"time {code.GetValue():g}"
