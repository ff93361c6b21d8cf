"""JSON as the ``--json`` options print it: strict (RFC 8259), every float that is not finite as
``null`` (Python's ``json`` writes ``NaN`` and ``Infinity``, which strict readers refuse)."""

from __future__ import annotations

import json
import math


def strict(value):
    """``value`` with every float that is not finite replaced by None (JSON null)."""
    if isinstance(value, dict):
        return {k: strict(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [strict(v) for v in value]
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def dumps(value, indent: int | None = None) -> str:
    """Strict JSON text of ``value`` (:func:`strict`)."""
    return json.dumps(strict(value), indent=indent, allow_nan=False)
