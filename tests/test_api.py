"""The public API (``dftl_warp/__init__.py``): the exact list, every name importable, each object
defined in the layer it belongs to, and ``import dftl_warp`` cheap (no Warp, no USD)."""

from __future__ import annotations

import importlib
import inspect
import subprocess
import sys

import pytest

import dftl_warp
from test_architecture import LAYERS, layer_of

PUBLIC = [
    "__version__",
    # ---- errors and options
    "UserError", "OptionError", "OPTIONS",
    # ---- model and state
    "Model", "State", "Control",
    # ---- solvers
    "Solver", "SOLVERS", "register_solver", "make_solver", "DEFAULT_GRAVITY",
    "DFTLSolver", "FTLSolver", "PBDSolver", "ReferenceSolver",
    # ---- features
    "features",
    # ---- USD in, frames out
    "read_scene", "Scene", "FrameWriter", "WRITERS", "register_writer", "writer_for", "UsdWriter",
    # ---- simulation
    "simulate_usd", "Simulation", "SimulationOptions", "Summary", "run_frames", "simulate_strands", "Recording",
    # ---- render
    "Renderer", "RenderScene", "Camera",
    # ---- importers
    "import_groom", "read_groom",
]

#: public name -> the layer (tests/test_architecture.py LAYERS) whose package defines it
LAYER = {
    "UserError": "foundation", "OptionError": "foundation", "OPTIONS": "foundation",
    "Model": "core", "State": "core", "Control": "core",
    "Solver": "solvers", "SOLVERS": "solvers", "register_solver": "solvers", "make_solver": "solvers",
    "DEFAULT_GRAVITY": "solvers", "DFTLSolver": "solvers", "FTLSolver": "solvers", "PBDSolver": "solvers",
    "ReferenceSolver": "solvers",
    "features": "features",
    "read_scene": "usd", "Scene": "usd",
    "FrameWriter": "output", "WRITERS": "output", "register_writer": "output", "writer_for": "output",
    "UsdWriter": "output",
    "simulate_usd": "simulation", "Simulation": "simulation", "SimulationOptions": "simulation",
    "Summary": "simulation", "run_frames": "simulation", "simulate_strands": "simulation", "Recording": "simulation",
    "Renderer": "study, render", "RenderScene": "study, render", "Camera": "study, render",
    "import_groom": "usd", "read_groom": "usd",
}


def test_all_is_exactly_the_public_list():
    assert dftl_warp.__all__ == PUBLIC
    assert set(LAYER) == set(PUBLIC) - {"__version__"}


@pytest.mark.parametrize("name", PUBLIC)
def test_every_public_name_imports(name):
    value = getattr(dftl_warp, name)
    assert value is not None
    exec(f"from dftl_warp import {name}", {})  # noqa: S102


def _defining_module(name: str, value) -> str:
    if inspect.ismodule(value):
        return value.__name__
    if inspect.isclass(value) or inspect.isfunction(value):
        return value.__module__
    # a constant: the module the lazy table names (checked to hold this very object)
    module, attribute = dftl_warp._PUBLIC[name]
    assert getattr(importlib.import_module(module), attribute) is value
    return module


@pytest.mark.parametrize("name", sorted(LAYER))
def test_every_public_object_lives_in_its_layer(name):
    module = _defining_module(name, getattr(dftl_warp, name))
    assert LAYERS[layer_of(module)][0] == LAYER[name], f"{name} is defined in {module}"


def test_public_names_are_the_registries_themselves():
    from dftl_warp.output import base
    from dftl_warp.solvers import base as solvers

    assert dftl_warp.SOLVERS is solvers.SOLVERS and {"dftl", "ftl", "pbd", "reference"} <= set(dftl_warp.SOLVERS)
    assert dftl_warp.WRITERS is base.WRITERS and dftl_warp.writer_for("x.usdc") is dftl_warp.UsdWriter
    assert issubclass(dftl_warp.UsdWriter, dftl_warp.FrameWriter)
    assert dftl_warp.make_solver.__module__ == "dftl_warp.solvers.base"


def test_unknown_attribute_is_an_attribute_error():
    with pytest.raises(AttributeError, match="no attribute 'nope'"):
        dftl_warp.nope  # noqa: B018


def test_import_is_cheap():
    code = ("import sys, dftl_warp\n"
            "heavy = sorted(m for m in ('warp', 'pxr', 'numpy') if m in sys.modules)\n"
            "assert not heavy, heavy\n"
            "assert dftl_warp.__version__\n")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0 and r.stdout == "" and r.stderr == "", r.stderr
