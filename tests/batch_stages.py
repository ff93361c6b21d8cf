"""Stages, job files and output comparison for the batch tests (not a test module)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
from pxr import Sdf

from usd_stages import add_curves, animated_xform, new_stage


def groom_stage(path, *, strands: int, vertices: int, end: int, spacing: float = 1.0, seed: int = 0):
    """Straight strands hanging from a plane under an Xform that translates and turns (cm, Y up)."""
    rng = np.random.default_rng(seed)
    stage = new_stage(path, meters_per_unit=0.01, start=1, end=end)
    animated_xform(stage, "/World/Head", translate={1: (0, 100, 0), end: (30, 100, 0)},
                   rotate_y={1: 0.0, end: 90.0})
    side = int(np.ceil(np.sqrt(strands)))
    roots = np.stack(np.meshgrid(np.arange(side), np.arange(side)), -1).reshape(-1, 2)[:strands] * 0.5
    roots = roots + rng.uniform(-0.1, 0.1, size=roots.shape)
    pts = []
    for x, z in roots:
        direction = np.array([rng.uniform(-0.3, 0.3), -1.0, rng.uniform(-0.3, 0.3)])
        direction /= np.linalg.norm(direction)
        pts.append(np.array([x, 0.0, z]) + np.arange(vertices)[:, None] * spacing * direction)
    add_curves(stage, "/World/Head/Hair", np.concatenate(pts), [vertices] * strands, widths=0.05)
    stage.GetRootLayer().Save()
    return Path(path)


def write_jobs(path, jobs: list[dict], defaults: dict | None = None) -> Path:
    """A JOBS.toml with the given [[job]] tables (values: str, int, float, list of str)."""

    def value(v):
        if isinstance(v, str):
            return '"' + v.replace("\\", "\\\\").replace('"', '\\"') + '"'
        if isinstance(v, list):
            return "[" + ", ".join(value(x) for x in v) + "]"
        return repr(v)

    lines = []
    if defaults:
        lines.append("[defaults]")
        lines += [f"{k} = {value(v)}" for k, v in defaults.items()]
    for job in jobs:
        lines.append("\n[[job]]")
        lines += [f"{k} = {value(v)}" for k, v in job.items()]
    Path(path).write_text("\n".join(lines) + "\n")
    return Path(path)


def batch_command(jobs_file, *args) -> list[str]:
    return [sys.executable, "-m", "dftl_warp", "batch", str(jobs_file), *map(str, args)]


def run_batch(jobs_file, *args, timeout=300) -> subprocess.CompletedProcess:
    return subprocess.run(batch_command(jobs_file, *args), capture_output=True, text=True, timeout=timeout,
                          cwd=Path(jobs_file).parent, env=dict(os.environ))


def layer_content(path) -> dict:
    """Every time sample (as bytes) and default value of every attribute spec, the prim specs and
    the layer metadata except customLayerData (which records the job's paths)."""
    layer = Sdf.Layer.OpenAsAnonymous(str(path))
    assert layer is not None, path
    content = {"sublayers": list(layer.subLayerPaths)}
    root = layer.pseudoRoot
    for key in root.ListInfoKeys():
        if key not in ("customLayerData", "subLayers", "subLayerOffsets"):
            content[f"meta:{key}"] = str(root.GetInfo(key))

    def visit(spec_path):
        spec = layer.GetObjectAtPath(spec_path)
        if isinstance(spec, Sdf.AttributeSpec):
            samples = {t: np.asarray(layer.QueryTimeSample(spec_path, t)).tobytes()
                       for t in layer.ListTimeSamplesForPath(spec_path)}
            content[str(spec_path)] = (str(spec.typeName), samples)
        elif isinstance(spec, Sdf.PrimSpec):
            content[str(spec_path)] = str(spec.specifier)

    layer.Traverse(Sdf.Path.absoluteRootPath, visit)
    return content


def hidden_files(folder) -> list[str]:
    return sorted(p.name for p in Path(folder).rglob(".*"))


class Interrupt(Exception):
    """Raised by :func:`stop_after` to cut a job short, as a kill would (tests of resuming)."""


def stop_after(frames: int):
    """A ``run_job`` progress callback that interrupts the job once ``frames`` frames are written."""
    def stop(event):
        if event["event"] == "frames" and event["done"] >= frames:
            raise Interrupt()
    return stop
