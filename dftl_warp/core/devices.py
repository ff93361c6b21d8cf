"""Warp devices for command-line use: quiet initialisation, the default device, device lists.

- :func:`init_warp` initialises Warp once, without its banner (unless ``DFTL_WARP_VERBOSE``).
  Nothing in dftl_warp initialises Warp at import time: ``import dftl_warp`` prints nothing.
- :func:`default_device` is what every command runs on without ``--device``: ``cuda:0`` when
  Warp finds a CUDA device, else ``cpu`` (``DFTL_WARP_DEVICE`` overrides it, e.g. to keep a CI
  machine with a GPU on the CPU).
- :func:`parse_devices` is the one parser of device lists (``cuda:0,cuda:1``).
- :func:`lookup_device` is Warp's device of a name, or one :class:`DeviceNotFound` listing the
  devices there are (each caller names the option or argument in its own words);
  :func:`device_argument` is the Python API's words: "device 'gpu' is not available here (cpu): ...".
"""

from __future__ import annotations

import contextlib
import os
import sys

from ..errors import UserError

#: environment variable naming the device used when a command gets no ``--device``
DEVICE_ENV = "DFTL_WARP_DEVICE"


class DeviceNotFound(ValueError):
    """A device this machine lacks; the message reads ``not available here (cpu, cuda:0): why``."""


def lookup_device(name):
    """Warp's device ``name`` (a Device, or a name such as ``cuda:0``); :class:`DeviceNotFound`
    for one Warp does not have here."""
    import warp as wp

    try:
        return wp.get_device(name)
    except (ValueError, RuntimeError, KeyError, TypeError) as exc:
        available = ", ".join(d.alias for d in wp.get_devices())
        raise DeviceNotFound(f"not available here ({available}): {exc}") from None


def device_argument(name, error: type = ValueError):
    """Warp's device ``name`` given as a ``device`` argument of the Python API; ``error`` (default
    ValueError) "device 'gpu' is not available here (cpu): ..." for one Warp does not have here
    (Warp's own "Invalid device identifier: gpu" named neither the argument nor the devices there are)."""
    try:
        return lookup_device(name)
    except DeviceNotFound as exc:
        raise error(f"device {name!r} is {exc}") from None


def init_warp() -> None:
    """Initialise Warp once. Without ``DFTL_WARP_VERBOSE``, its banner and the native
    'no CUDA driver' notice of CPU-only machines are kept off the terminal."""
    import warp as wp

    if os.environ.get("DFTL_WARP_VERBOSE"):
        wp.init()
        return
    wp.config.quiet = True
    wp.config.log_level = wp.LOG_WARNING
    with _stderr_silenced():
        wp.init()


def parse_devices(text) -> list[str]:
    """``"cuda:0,cuda:1"`` -> ``["cuda:0", "cuda:1"]`` (names as given, blanks removed); a
    UserError for an empty list or an empty name in it."""
    devices = [d.strip() for d in str(text).split(",")]
    if not all(devices):
        raise UserError(f"--device {text}: empty device name in the list")
    return devices


def default_device() -> str:
    """``$DFTL_WARP_DEVICE`` if set, else ``cuda:0`` when Warp finds a CUDA device, else ``cpu``."""
    chosen = os.environ.get(DEVICE_ENV, "").strip()
    import warp as wp

    init_warp()
    if chosen:   # checked here, so a bad value is reported as the variable's, not as --device's
        for name in (d.strip() for d in chosen.split(",")):
            try:
                if not name:
                    available = ", ".join(d.alias for d in wp.get_devices())
                    raise DeviceNotFound(f"not available here ({available}): empty device name in the list")
                lookup_device(name)
            except DeviceNotFound as exc:
                raise UserError(f"${DEVICE_ENV}={chosen}: device {name or repr(name)} is {exc}; set it to one of "
                                "them or unset it") from None
        return chosen
    return "cuda:0" if wp.get_cuda_device_count() > 0 else "cpu"


def resolve_device(device) -> str:
    """``device`` as given, or :func:`default_device` when it is None or empty."""
    if device is None or not str(device).strip():
        return default_device()
    return str(device)


def device_line(device) -> str:
    """One line saying which device(s) a command runs on, e.g.
    ``dftl-warp: device cuda:0 (NVIDIA H100 80GB HBM3)``."""
    import warp as wp

    init_warp()
    names = []
    for name in parse_devices(device):
        try:
            d = wp.get_device(name)
            names.append(f"{d.alias} ({d.name})" if d.is_cuda else d.alias)
        except (ValueError, RuntimeError, KeyError):
            names.append(name)
    return f"dftl-warp: device {', '.join(names)}"


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
