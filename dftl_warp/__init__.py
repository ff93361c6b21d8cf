"""dftl-warp: GPU hair simulation with Dynamic Follow-The-Leader on NVIDIA Warp.

Data flows one way: USD -> :class:`Model` -> :class:`State` -> solver -> writer / renderer.
"""

from pathlib import Path as _Path

# In a source checkout (not installed) the kernels live in ../kernels; installed, they are the
# subpackage dftl_warp/kernels. Either way they import as ``dftl_warp.kernels``.
if not (_Path(__file__).parent / "kernels").is_dir():
    __path__.append(str(_Path(__file__).resolve().parent.parent))  # noqa: F821

__version__ = "0.1.0"

from .api import Recording, simulate_strands  # noqa: E402
from .model import Model  # noqa: E402
from .solver import DFTLSolver, make_solver  # noqa: E402
from .state import Control, State  # noqa: E402

__all__ = ["Model", "State", "Control", "DFTLSolver", "make_solver", "simulate_strands", "Recording"]
