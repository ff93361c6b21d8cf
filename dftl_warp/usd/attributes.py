"""The ``dftl:`` attributes of a prim, checked against the one table (:mod:`dftl_warp.options`).

- :func:`read_values` reads the authored attributes a prim of one scope holds, checks each value
  (type and range) and returns them by attribute name; a bad value raises
  :class:`~dftl_warp.errors.UserError` naming file, prim and attribute.
- :func:`unknown_attributes` warns (once per prim, with a did-you-mean) about authored ``dftl:``
  attributes the table does not know, and about known ones on prims that do not read them. The
  attributes dftl-warp itself writes into its outputs (:data:`OUTPUT_ATTRIBUTES`: the per-frame QC,
  ``dftl:qc:*`` on ``/dftl_qc/*``) are known: a cache read back (``info``, or ``simulate`` of a
  cache) gets no warning for them.
"""

from __future__ import annotations

import numpy as np

from ..errors import UserError
from ..options import BY_USD, NAMESPACE, BadValue, shown_value, unknown_message, usd_attributes, usd_message
from .values import shown

#: the namespace of the per-frame QC dftl-warp writes into its outputs (dftl_warp.output.qc)
QC_NAMESPACE = "dftl:qc:"
#: the attribute naming the simulated prim on each QC prim (written by dftl_warp.output.usd)
QC_PRIM_ATTRIBUTE = "dftl:qc:prim"
#: the ``dftl:`` attributes dftl-warp writes into its outputs: the QC prim's name and the values of
#: ``dftl_warp.output.qc.ATTRIBUTES`` (spelled out here: the reader imports no output module;
#: tests/test_usd_attributes_messages.py checks the two agree)
OUTPUT_ATTRIBUTES = frozenset({QC_PRIM_ATTRIBUTE, "dftl:qc:maxStretch", "dftl:qc:maxPenetration", "dftl:qc:maxSpeed",
                               "dftl:qc:energy", "dftl:qc:nanCount"})

#: which prims read each scope, for the "not read here" warning
_SCOPE_TEXT = {
    "curves": "BasisCurves prims",
    "scene": "the UsdPhysics.Scene prim (else the default prim)",
    "both": "BasisCurves prims and the UsdPhysics.Scene prim (else the default prim)",
    "collider": "prims with UsdPhysics.CollisionAPI",
}


def read_values(prim, where: str, scope: str, time_codes_per_second: float) -> dict:
    """The authored ``dftl:`` attributes of ``prim`` read in ``scope`` ("curves", "scene",
    "collider"), checked: attribute name -> value (bool, int, float; a time-sampled ``float3``
    such as ``dftl:wind`` becomes keyframes (K, 4) of (seconds, x, y, z)). Relationships are
    left to their readers."""
    values = {}
    for option in usd_attributes(scope):
        name = option.usd
        if option.type == "rel":
            continue
        attr = prim.GetAttribute(name)
        if not attr or not attr.HasAuthoredValue():
            continue
        if option.type == "float3":
            times = attr.GetTimeSamples()
            rows = [(t, attr.Get(t)) for t in times] if times else [(0.0, attr.Get())]
            keys = []
            for t, v in rows:
                try:
                    v = np.array(v, dtype=np.float64).reshape(3)
                except (TypeError, ValueError):
                    raise UserError(f"{where}: {name} = {shown(v)}: expected 3 numbers") from None
                if not np.isfinite(v).all():
                    raise UserError(f"{where}: {name} at time {t:g} is not finite")
                keys.append([t / time_codes_per_second, *v])
            values[name] = np.array(keys) if times else np.array(keys[0][1:])
            continue
        if option.retired:
            raise UserError(f"{where}: {name}: {option.retired}")
        value = attr.Get()
        _refuse_time_samples(attr, value, name, where)
        try:
            option.check(value)
        except BadValue as exc:
            message = usd_message(exc, where, attr=attr)
            if not isinstance(value, (bool, int, float, str, np.generic)):   # a Vt array: plain values
                message = message.replace(f"= {shown_value(exc.value, attr)}", f"= {shown(value)}", 1)
            raise UserError(message) from None
        values[name] = value
    return values


def _refuse_time_samples(attr, value, name: str, where: str) -> None:
    """UserError when the one-value ``dftl:`` attribute ``attr`` has time samples that hold another
    value than its default ``value`` (or it has no default): it is read once, not over time (only
    ``float3`` attributes such as ``dftl:wind`` are read as keyframes)."""
    times = attr.GetTimeSamples()
    if not times:
        return
    if value is not None and all(np.array_equal(np.asarray(attr.Get(t)), np.asarray(value)) for t in times):
        return
    animated = ", ".join(o.usd for o in BY_USD.values() if o.type == "float3")
    span = f"at time {times[0]:g}" if len(times) == 1 else f"at times {times[0]:g}..{times[-1]:g}"
    raise UserError(f"{where}: {name} is time-sampled ({len(times)} sample{'s' if len(times) > 1 else ''} {span}"
                    f"{'' if value is not None else ', no default value'}): not supported, it is read once for the "
                    f"whole shot (only {animated} can be animated); author one value, without timeSamples")


def authored_names(prim) -> list[str]:
    """Names of the ``dftl:`` properties authored on ``prim`` (attributes and relationships)."""
    return [p.GetName() for p in prim.GetAuthoredPropertiesInNamespace(NAMESPACE.rstrip(":"))]


def unknown_attributes(prim, where: str, scopes) -> str | None:
    """One warning for ``prim`` (or None): its authored ``dftl:`` attributes that the table does not
    know (with a did-you-mean), and the known ones that prims of ``scopes`` do not read."""
    names = authored_names(prim)
    if not names:
        return None
    names = [n for n in names if n not in OUTPUT_ATTRIBUTES]  # dftl-warp's own output: known
    unknown = [n for n in names if n not in BY_USD]
    misplaced = []
    for n in names:
        option = BY_USD.get(n)
        if option is None:
            continue
        reads = set(scopes)
        if option.scope in reads or (option.scope == "both" and reads & {"curves", "scene"}):
            continue
        misplaced.append(f"{n} (read on {_SCOPE_TEXT[option.scope]})")
    parts = []
    if unknown:
        parts.append(unknown_message(unknown, BY_USD,
                                     lambda n: OUTPUT_ATTRIBUTES if n.startswith(QC_NAMESPACE) else BY_USD))
    if misplaced:
        parts.append("not read on this prim: " + ", ".join(misplaced))
    if not parts:
        return None
    return f"{where}: {'; '.join(parts)}; ignored"
