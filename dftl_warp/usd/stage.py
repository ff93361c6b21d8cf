"""A stage's metadata and gravity, and USD's error messages on one line.

- :func:`read_stage_info`: ``upAxis``, ``metersPerUnit``, ``timeCodesPerSecond`` ... (USD's
  fallbacks applied); a zero, negative or non-finite ``timeCodesPerSecond`` or ``metersPerUnit``,
  or an ``upAxis`` other than "Y" and "Z", raises :class:`~dftl_warp.errors.UserError` naming the file;
- :func:`layer_unit_warnings`: composed layers authored in other units or another up axis;
- :func:`read_gravity`: from the first ``UsdPhysics.Scene`` prim, else 9.81 m/s^2 along -upAxis;
- :func:`tf_message`: the first message of a ``Tf.ErrorException`` on one line (the reader's and
  the writer's error messages), also when it holds bytes that are not UTF-8 (:func:`utf8_problem`
  says where a text file has them).
"""

from __future__ import annotations

import math
import os
import re

import numpy as np

from ..errors import UserError
from .scene import StageInfo
from .values import number, numbers3, shown

#: standard gravity, m/s^2
STANDARD_GRAVITY = 9.81


def exception_text(exc: Exception) -> str:
    """``str(exc)``, also when a message of a Tf.ErrorException holds bytes that are not UTF-8 (a
    Latin-1 character in a .usda file: Python's ``str`` of the Tf.Error raises UnicodeDecodeError);
    those bytes become U+FFFD."""
    try:
        return str(exc)
    except UnicodeDecodeError:
        pass
    parts = []
    for item in getattr(exc, "args", ()):
        try:
            parts.append(str(item))
        except UnicodeDecodeError as bad:
            parts.append(bytes(bad.object).decode("utf-8", errors="replace"))
    return "\n\t" + "\n\t".join(parts) if parts else type(exc).__name__


def diagnostic_text(diagnostic) -> str:
    """The commentary of a USD diagnostic (a warning collected while composing), bytes that are not
    UTF-8 shown as U+FFFD."""
    try:
        return diagnostic.commentary
    except UnicodeDecodeError as bad:
        return bytes(bad.object).decode("utf-8", errors="replace")


def utf8_problem(path: str) -> str | None:
    """Where the text file ``path`` is not valid UTF-8: ``not valid UTF-8 (byte 0xe9 at line 11,
    column 6)``; None when it is (or cannot be read)."""
    try:
        with open(path, "rb") as f:
            data = f.read()
    except OSError:
        return None
    try:
        data.decode("utf-8")
    except UnicodeDecodeError as bad:
        at = bad.start
        line = data.count(b"\n", 0, at) + 1
        column = at - (data.rfind(b"\n", 0, at) + 1) + 1
        return f"not valid UTF-8 (byte 0x{data[at]:02x} at line {line}, column {column})"
    return None


def tf_message(exc: Exception) -> str:
    """The first message of a Tf.ErrorException, on one line, without C++ decorations (bytes that
    are not UTF-8 shown as U+FFFD)."""
    text = exception_text(exc)
    found = re.findall(r"Error in '[^']*' at line \d+ in file [^:]+ : '(.*?)'\s*(?=\n\tError in|$)", text, re.S)
    message = found[0] if found else text.strip()
    message = re.sub(r"pxrInternal_v[0-9_]+?__pxrReserved__(_?)::", "", message)
    message = re.sub(r"\bSdf_\w+::|\b_pegtl::", "", message)
    return " ".join(message.split())


def open_failure(path: str, exc: Exception) -> UserError:
    """The one-line error for a stage USD could not open (``exc``, a Tf.ErrorException): bytes that
    are not UTF-8 named by line and column, a parse error as ``FILE:LINE:COLUMN: syntax error: ...``,
    else ``FILE: cannot open as a USD stage: REASON``."""
    message = tf_message(exc)
    # USD read bytes that are not UTF-8 (a Latin-1 character in a .usda): its message holds U+FFFD or,
    # opened without a diagnostic delegate, says only that the layer is not valid usda
    if "\ufffd" in message or os.fspath(path).lower().endswith(".usda"):
        problem = utf8_problem(path)
        if problem is not None:
            return UserError(f"{path}: cannot open as a USD stage: {problem}: USD text files are UTF-8 "
                             f"(save the file as UTF-8)")
    prefix = os.path.abspath(path) + ":"
    if message.startswith(prefix):  # parser messages start with the file name
        message = message[len(prefix):].lstrip()
        where = re.match(r"(\d+:\d+):\s*(.*)", message, re.S)
        if where:
            return UserError(f"{path}:{where.group(1)}: syntax error: {where.group(2)}")
        return UserError(f"{path}: {message}")
    return UserError(f"{path}: cannot open as a USD stage: {message}")


def read_stage_info(stage, file: str | None = None) -> StageInfo:
    """Effective stage metadata (USD fallbacks applied) and which fields the root layer authors.

    A ``timeCodesPerSecond`` or ``metersPerUnit`` that is not a positive finite number raises
    :class:`UserError` naming ``file`` (default: the root layer).
    """
    from pxr import UsdGeom

    root = stage.GetRootLayer()
    authored = tuple(
        k for k in ("upAxis", "metersPerUnit", "timeCodesPerSecond", "framesPerSecond",
                    "startTimeCode", "endTimeCode", "defaultPrim")
        if root.pseudoRoot.HasInfo(k)
    )
    has_range = stage.HasAuthoredTimeCodeRange()
    file = file or root.identifier
    for name, value in (("timeCodesPerSecond", stage.GetTimeCodesPerSecond()),
                        ("metersPerUnit", UsdGeom.GetStageMetersPerUnit(stage))):
        if not (math.isfinite(value) and value > 0):
            raise UserError(f"{file}: {name} = {value:g}: must be a positive number")
    up_axis = str(UsdGeom.GetStageUpAxis(stage))
    if up_axis not in ("Y", "Z"):
        raise UserError(f"{file}: upAxis = {up_axis!r}: must be \"Y\" or \"Z\" (USD's only up axes)")
    if has_range:
        for name, value in (("startTimeCode", stage.GetStartTimeCode()), ("endTimeCode", stage.GetEndTimeCode())):
            if not math.isfinite(value):
                raise UserError(f"{file}: {name} = {value:g}: must be a finite number")
    from pxr import UsdPhysics

    kpu = float(UsdPhysics.GetStageKilogramsPerUnit(stage))
    if not (math.isfinite(kpu) and kpu > 0):
        raise UserError(f"{file}: kilogramsPerUnit = {kpu:g}: must be a positive number")
    return StageInfo(
        up_axis=up_axis,
        meters_per_unit=float(UsdGeom.GetStageMetersPerUnit(stage)),
        kilograms_per_unit=kpu,
        time_codes_per_second=float(stage.GetTimeCodesPerSecond()),
        frames_per_second=float(stage.GetFramesPerSecond()) if root.HasFramesPerSecond() else None,
        start_time_code=float(stage.GetStartTimeCode()) if has_range else None,
        end_time_code=float(stage.GetEndTimeCode()) if has_range else None,
        default_prim=str(root.defaultPrim or ""),
        authored=authored,
    )


def layer_unit_warnings(stage, info: StageInfo, file: str) -> list[str]:
    """One line per layer the stage uses (sublayered, referenced, payloaded) whose authored
    ``metersPerUnit`` or ``upAxis`` differs from the stage's: USD composes such layers without
    converting them, so their prims are read in the stage's units and axes."""
    out = []
    skip = {stage.GetRootLayer().identifier, stage.GetSessionLayer().identifier}
    for layer in stage.GetUsedLayers():
        if layer.identifier in skip:
            continue
        root, ours, theirs = layer.pseudoRoot, [], []
        if root.HasInfo("metersPerUnit"):
            value = float(root.GetInfo("metersPerUnit"))
            if not math.isclose(value, info.meters_per_unit, rel_tol=1e-9):
                ours.append(f"{info.meters_per_unit:g}")
                theirs.append(f"metersPerUnit {value:g}")
        if root.HasInfo("upAxis") and str(root.GetInfo("upAxis")) != info.up_axis:
            ours.append(info.up_axis)
            theirs.append(f"upAxis {root.GetInfo('upAxis')}")
        if theirs:
            out.append(f"{file}: layer {layer.identifier} has {' and '.join(theirs)}, but the stage's "
                       f"{'are' if len(ours) > 1 else 'is'} {' and '.join(ours)}: USD does not convert the layers a "
                       f"stage composes, so its prims are read in the stage's units and axes (scale or rotate the "
                       f"prim that brings it in)")
    return out


def up_vector(up_axis: str) -> np.ndarray:
    return np.array([0.0, 0.0, 1.0]) if up_axis == "Z" else np.array([0.0, 1.0, 0.0])


def read_gravity(stage, info: StageInfo, file: str, warnings: list) -> np.ndarray:
    """Gravity (3,) in stage units/s^2.

    From the first ``UsdPhysics.Scene`` prim: ``gravityDirection`` (a zero vector means -upAxis)
    times ``gravityMagnitude`` (negative means earth gravity, 9.81 m/s^2 in stage units). Without
    a physics scene: 9.81 m/s^2 along -upAxis.
    """
    from pxr import UsdPhysics

    earth = STANDARD_GRAVITY / info.meters_per_unit
    default = -up_vector(info.up_axis) * earth + 0.0  # + 0.0: no negative zeros
    scenes = [p for p in stage.Traverse() if p.IsA(UsdPhysics.Scene)]
    if not scenes:
        return default
    if len(scenes) > 1:
        warnings.append(f"{file}: {len(scenes)} UsdPhysics.Scene prims; using {scenes[0].GetPath()}")
    phys = UsdPhysics.Scene(scenes[0])
    where = f"{file}: {scenes[0].GetPath()}"
    direction = phys.GetGravityDirectionAttr().Get()
    direction = np.zeros(3) if direction is None else numbers3(direction, "physics:gravityDirection", where)
    magnitude = phys.GetGravityMagnitudeAttr().Get()
    magnitude = float("-inf") if magnitude is None else number(magnitude, "physics:gravityMagnitude", where)
    if not np.all(np.isfinite(direction)):
        raise UserError(f"{where}: gravityDirection {shown(tuple(direction))} is not finite")
    if np.isnan(magnitude) or magnitude == float("inf"):
        raise UserError(f"{where}: gravityMagnitude {shown(magnitude)} is not finite")
    norm = float(np.linalg.norm(direction))
    unit = -up_vector(info.up_axis) if norm == 0.0 else direction / norm
    return unit * (earth if magnitude < 0.0 else magnitude) + 0.0
