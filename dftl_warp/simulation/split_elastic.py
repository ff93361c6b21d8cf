"""Elastic strands on several devices: the elastic solver's interface over the parts of a split group.

The elastic solver's strands are independent of each other, as DFTL's are, so a group split across
devices (:mod:`~dftl_warp.simulation.multi_device`) gives every part its own
:class:`~dftl_warp.solvers.elastic.ElasticSolver`, built from the part's slice of the per-point
material (radius, twist modulus, stiffness scale, rest shape). :class:`SplitElasticSolver` presents
what the simulation asks of the one solver: the clamps (per strand, cut at the parts' strand
ranges), the stability and hinge checks (over all the parts' strands, as on one device), the clean
start's rest shapes and the energy. Strand indices are the group's input order throughout; part
``k`` holds strands ``s0:s1`` of it.
"""

from __future__ import annotations

import numpy as np

from ..solvers.elastic import ElasticSolver
from .multi_device import SplitSolver

#: the elastic solver's per-point keywords a split group cuts at its parts' point ranges
PER_POINT = ("radius", "twist_modulus", "stiffness_scale", "rest_shape")


def part_options(options: dict, p0: int, p1: int) -> dict:
    """``options`` (make_solver keywords of the elastic solver) for the part holding points ``p0:p1``."""
    out = dict(options)
    for name in PER_POINT:
        value = out.get(name)
        if value is not None and np.ndim(value) > 0:
            out[name] = np.asarray(value)[p0:p1]
    return out


class SplitElasticSolver(SplitSolver):
    """The parts' elastic solvers seen as one (their models: strands ``s0:s1`` of the group for
    each ``(s0, s1)`` of ``strand_ranges``)."""

    name = ElasticSolver.name

    def __init__(self, solvers, strand_ranges):
        super().__init__(solvers)
        self.strand_ranges = [(int(a), int(b)) for a, b in strand_ranges]
        first = self.parts[0]
        self.inverse_statics = first.inverse_statics
        self.compute_precision = first.compute_precision
        self.correction = first.correction
        self.damping = first.damping

    @property
    def _groups(self) -> list:
        """The rods of every part, their strand indices in the group's input order: the checks run
        over them as over one device's (the stability test's sample draws from all strands at once;
        a part's rods change when it adopts a rest shape)."""
        return [(n, idx + s0, grp) for solver, (s0, _) in zip(self.parts, self.strand_ranges)
                for n, idx, grp in solver._groups]

    unheld_vertices = ElasticSolver.unheld_vertices
    unstable_strands = ElasticSolver.unstable_strands
    unchecked_strands = ElasticSolver.unchecked_strands

    @property
    def stiffness_scale(self) -> np.ndarray:
        return np.concatenate([s.stiffness_scale for s in self.parts])

    @property
    def authored_clamps(self) -> np.ndarray:
        """The authored clamp ghosts (S, 3), world coordinates, input strand order."""
        return np.concatenate([s.authored_clamps for s in self.parts])

    def set_clamp_targets(self, start=None, end=None, **path) -> None:
        """Every part's clamp targets (:meth:`ElasticSolver.set_clamp_targets
        <dftl_warp.solvers.elastic.ElasticSolver.set_clamp_targets>`), the per-strand arrays cut at
        the parts' strand ranges."""
        for solver, (s0, s1) in zip(self.parts, self.strand_ranges):
            cut = {k: v if v is None or np.ndim(v) == 0 else np.asarray(v)[s0:s1] for k, v in path.items()}
            solver.set_clamp_targets(None if start is None else np.asarray(start)[s0:s1],
                                     None if end is None else np.asarray(end)[s0:s1], **cut)

    def bind_clamps(self, control) -> None:
        for solver, c in zip(self.parts, control.parts):
            solver.bind_clamps(c)

    def moved_strands(self, state) -> np.ndarray:
        return np.concatenate([solver.moved_strands(s) + s0 for solver, s, (s0, _) in
                               zip(self.parts, state.parts, self.strand_ranges)])

    def adopt_rest_shape(self, state, strands=None) -> np.ndarray:
        """Every part adopts the rest shape of its own ``strands`` (group input indices; by default
        those moved from their rest shape); returns the group's input indices that changed."""
        adopted = []
        strands = None if strands is None else np.asarray(strands, dtype=np.int64).reshape(-1)
        for solver, s, (s0, s1) in zip(self.parts, state.parts, self.strand_ranges):
            own = None if strands is None else strands[(strands >= s0) & (strands < s1)] - s0
            adopted.append(solver.adopt_rest_shape(s, strands=own) + s0)
        return np.concatenate(adopted)

    def energy(self, state) -> float:
        """Kinetic + gravitational + elastic energy of all parts' strands (J, or the model's units)."""
        return float(sum(solver.energy(s) for solver, s in zip(self.parts, state.parts)))
