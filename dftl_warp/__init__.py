"""dftl-warp: GPU hair simulation with Dynamic Follow-The-Leader on NVIDIA Warp.

Data flows one way: USD -> :class:`Scene` -> :class:`Model` -> :class:`State` / :class:`Control`
-> solver -> frame writer / renderer. This module is the public API: every name below is what a
script needs, and ``docs/`` uses only these. They are imported on first use (``import dftl_warp``
loads neither Warp nor USD); ``tests/test_api.py`` pins the list.

>>> import dftl_warp as dw
>>> dw.simulate_usd("groom.usda", "groom_sim.usdc", substeps=16)
>>> model = dw.Model.from_strands(points, counts, device="cuda:0")
>>> solver = dw.make_solver(model, "dftl")
"""

from __future__ import annotations

import importlib

from .version import __version__

#: public name -> (module, attribute in it; None: the module itself)
_PUBLIC = {
    # ---- errors and options
    "UserError": ("dftl_warp.errors", "UserError"),
    "OptionError": ("dftl_warp.options", "OptionError"),
    "OPTIONS": ("dftl_warp.options", "OPTIONS"),
    # ---- model and state
    "Model": ("dftl_warp.core.model", "Model"),
    "State": ("dftl_warp.core.state", "State"),
    "Control": ("dftl_warp.core.state", "Control"),
    # ---- solvers
    "Solver": ("dftl_warp.solvers.base", "Solver"),
    "SOLVERS": ("dftl_warp.solvers.base", "SOLVERS"),
    "register_solver": ("dftl_warp.solvers.base", "register"),
    "make_solver": ("dftl_warp.solvers.base", "make_solver"),
    "DEFAULT_GRAVITY": ("dftl_warp.solvers.base", "DEFAULT_GRAVITY"),
    "DFTLSolver": ("dftl_warp.solvers.dftl", "DFTLSolver"),
    "FTLSolver": ("dftl_warp.solvers.dftl", "FTLSolver"),
    "PBDSolver": ("dftl_warp.solvers.pbd", "PBDSolver"),
    "ReferenceSolver": ("dftl_warp.solvers.reference", "ReferenceSolver"),
    # ---- features (colliders, root binding, drag and wind, hair-hair)
    "features": ("dftl_warp.features", None),
    # ---- USD in, frames out
    "read_scene": ("dftl_warp.usd.read", "read_scene"),
    "Scene": ("dftl_warp.usd.scene", "Scene"),
    "FrameWriter": ("dftl_warp.output.base", "FrameWriter"),
    "WRITERS": ("dftl_warp.output.base", "WRITERS"),
    "register_writer": ("dftl_warp.output.base", "register_writer"),
    "writer_for": ("dftl_warp.output.base", "writer_for"),
    "UsdWriter": ("dftl_warp.output.usd", "UsdWriter"),
    # ---- simulation
    "simulate_usd": ("dftl_warp.simulation.simulate", "simulate_usd"),
    "Simulation": ("dftl_warp.simulation.simulate", "Simulation"),
    "SimulationOptions": ("dftl_warp.simulation.settings", "SimulationOptions"),
    "Summary": ("dftl_warp.simulation.simulate", "Summary"),
    "run_frames": ("dftl_warp.simulation.simulate", "run_frames"),
    "simulate_strands": ("dftl_warp.simulation.strands", "simulate_strands"),
    "Recording": ("dftl_warp.simulation.strands", "Recording"),
    # ---- render
    "Renderer": ("dftl_warp.render.renderer", "Renderer"),
    "RenderScene": ("dftl_warp.render.scene", "RenderScene"),
    "Camera": ("dftl_warp.render.camera", "Camera"),
    # ---- importers
    "import_groom": ("dftl_warp.importers.convert", "import_groom"),
    "read_groom": ("dftl_warp.importers", "read_groom"),
}

__all__ = ["__version__", *_PUBLIC]


def __getattr__(name: str):
    try:
        module, attribute = _PUBLIC[name]
    except KeyError:
        raise AttributeError(f"module 'dftl_warp' has no attribute {name!r}") from None
    for registry in ("dftl_warp.output", "dftl_warp.solvers"):
        if module.startswith(registry + "."):
            importlib.import_module(registry)  # its package registers the writers / solvers first
    module_object = importlib.import_module(module)
    value = module_object if attribute is None else getattr(module_object, attribute)
    globals()[name] = value
    return value


def __dir__():
    return sorted(set(globals()) | set(__all__))
