"""Solvers: advance a State by substeps (:mod:`.base`: the interface and the registry).

Each solver module registers itself on import; this list is the registry's one line per solver.
"""

from . import dftl, pbd, reference  # noqa: F401  (registers dftl, ftl, pbd, reference)
from . import elastic  # noqa: F401  (registers elastic, opt-in)
from . import rattle  # noqa: F401  (registers rattle, the second-order production solver)
from .base import (DEFAULT_GRAVITY, SOLVERS, Solver, build_solver, carries_corrections, make_solver, register,  # noqa: F401
                   solver_class)
from .dftl import DFTLSolver, FTLSolver  # noqa: F401
from .pbd import PBDSolver  # noqa: F401
from .reference import ReferenceSolver  # noqa: F401
