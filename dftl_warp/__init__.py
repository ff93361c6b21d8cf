"""dftl-warp: GPU hair simulation with Dynamic Follow-The-Leader on NVIDIA Warp.

Data flows one way: USD -> :class:`Model` -> :class:`State` -> solver -> writer / renderer.
"""

from .version import __version__  # noqa: F401

from .simulation.strands import Recording, simulate_strands  # noqa: E402
from .core.model import Model  # noqa: E402
from .solvers import DFTLSolver, make_solver  # noqa: E402
from .core.state import Control, State  # noqa: E402

__all__ = ["Model", "State", "Control", "DFTLSolver", "make_solver", "simulate_strands", "Recording"]
