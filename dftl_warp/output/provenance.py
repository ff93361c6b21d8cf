"""Provenance: how an output was made, stored as the writer record :data:`RECORD` (USD: the output
layer's ``customLayerData["dftl_warp_provenance"]``) and printed by ``dftl-warp info OUTPUT``.

The record (``docs/caches.md``):

- ``version``, ``command`` (the command line, or ``python API``), ``date`` (UTC, ISO 8601), ``device``
  (names and kinds), ``host``;
- ``input``: ``path`` (absolute) and ``sha256`` (of the input file), and ``files``: SHA-256 of the
  input and of every file it depends on (sublayers, references, payloads, assets) by real path,
  :func:`input_fingerprint` (the one fingerprint: batch's settings hash uses it too);
- ``output``: ``frame_step``, ``velocities``, ``check``, ``clips``;
- ``groups``: ``group0``, ``group1``, ... one per simulation group: ``prims``, ``solver``,
  ``correction`` (form), ``damping``, ``substeps``, ``precision``, ``quality`` (preset or "none"),
  ``tolerance`` (the solver's, where it has one), ``iterations``, ``features``, ``strands``.

Values are str, int, float, bool or nested dicts (what every format's records and USD's
``customLayerData`` hold); lists are written comma-separated.
"""

from __future__ import annotations

import hashlib
import os
import sys
from dataclasses import asdict, is_dataclass

#: name of the provenance record
RECORD = "dftl_warp_provenance"


def file_sha256(path) -> str:
    digest = hashlib.sha256()
    with open(path, "rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            digest.update(chunk)
    return digest.hexdigest()


def input_fingerprint(input_path) -> dict:
    """SHA-256 of the input file and of every file it depends on (sublayers, references,
    payloads, other assets), by real path; missing dependencies are listed as such."""
    from pxr import UsdUtils

    files = {os.path.abspath(input_path): file_sha256(input_path)}
    delegate = UsdUtils.CoalescingDiagnosticDelegate()  # keep USD's warnings off the terminal
    try:
        layers, assets, unresolved = UsdUtils.ComputeAllDependencies(os.fspath(input_path))
    except Exception:  # noqa: BLE001 - the input alone still identifies most changes
        return files
    finally:
        del delegate
    for path in [layer.realPath for layer in layers if layer.realPath] + list(assets):
        if os.path.isfile(path):
            files[os.path.abspath(path)] = file_sha256(path)
    for path in unresolved:
        files[str(path)] = "missing"
    return files


def _plain(value):
    """A value a record can hold: str, int, float, bool, or a dict of those."""
    if isinstance(value, dict):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple, set, frozenset)):
        items = sorted(value) if isinstance(value, (set, frozenset)) else value
        return ",".join(str(v) for v in items)
    if value is None:
        return "none"
    if isinstance(value, (bool, int, float, str)):
        return value
    if hasattr(value, "item"):
        return value.item()
    return str(value)


def command_line() -> str:
    """The command line of this process (``dftl-warp simulate ...``), or ``python API``."""
    import shlex

    argv = list(sys.argv)
    if not argv or not argv[0] or argv[0] == "-c":
        return "python API"
    name = os.path.basename(argv[0])
    if name in ("dftl-warp", "__main__.py"):
        argv[0] = "dftl-warp"
    return shlex.join(argv)


def build(sim, input_path, *, output_options: dict, quality=None, fingerprint: dict | None = None,
          command: str | None = None) -> dict:
    """The provenance record of a run of :class:`~dftl_warp.simulation.simulate.Simulation` ``sim``
    on ``input_path`` (``fingerprint``: an :func:`input_fingerprint` already computed)."""
    import datetime
    import platform

    from ..core.devices import parse_devices
    from ..version import __version__

    files = fingerprint if fingerprint is not None else input_fingerprint(input_path)
    source = os.path.abspath(os.fspath(input_path))
    devices = {}
    try:
        import warp as wp

        for name in parse_devices(sim.options.device):
            d = wp.get_device(name)
            devices[name] = d.name if d.is_cuda else (platform.processor() or platform.machine() or "cpu")
    except Exception:  # noqa: BLE001 - the names alone still say where it ran
        devices = {name: name for name in parse_devices(sim.options.device)}
    groups = {}
    for k, g in enumerate(sim.groups):
        s = g.settings
        solver = g.solver.parts[0] if hasattr(g.solver, "parts") else g.solver
        tolerance = getattr(solver, "tolerance", None)
        groups[f"group{k}"] = {
            "prims": [sim.scene.curves[i].path for i in g.members],
            **(asdict(s) if is_dataclass(s) else dict(vars(s))),  # solver, correction (form), damping, substeps, ...
            "precision": sim.options.precision,
            "arithmetic": getattr(solver, "compute_precision", None) or "none",
            "quality": quality or "none", "tolerance": "none" if tolerance is None else float(tolerance),
            "iterations": getattr(solver, "iterations", None) or "none",
            "features": sorted(g.model.feature_flags) or "none", "strands": int(g.num_strands),
        }
    record = {
        "version": __version__,
        "command": command or command_line(),
        "date": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
        "host": platform.node(),
        "device": devices,
        "input": {"path": source, "sha256": files.get(source, "")},
        "files": {f"file{k}": {"path": p, "sha256": h} for k, (p, h) in enumerate(sorted(files.items()))},
        "output": output_options,
        "groups": groups,
    }
    return _plain(record)


def read(path) -> dict | None:
    """The provenance record of the finished output ``path``, or None."""
    from . import WRITERS

    from pathlib import Path

    cls = WRITERS.get(Path(os.fspath(path)).suffix.lower())
    if cls is None or not Path(os.fspath(path)).is_file():
        return None
    return cls.read_record(path, RECORD)


def lines(record: dict, indent: str = "  ") -> list[str]:
    """``record`` as indented ``key  value`` lines (``dftl-warp info``)."""
    out = []

    def walk(d, depth):
        for key in sorted(d, key=lambda k: (isinstance(d[k], dict), k)):
            value = d[key]
            if isinstance(value, dict):
                out.append(f"{indent * depth}{key}")
                walk(value, depth + 1)
            else:
                out.append(f"{indent * depth}{key:<12} {value}")

    walk(record, 1)
    return out
