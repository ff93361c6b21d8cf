"""The reference solver: the true inextensible-chain dynamics, integrated by RATTLE in float64.

Independent of follow-the-leader, it is what the accuracy study measures DFTL, FTL and PBD
against. Same interface as :class:`~dftl_warp.solvers.dftl.DFTLSolver` (``state``, ``step``, ``advance``,
``diagnostics``). Equal unit masses, kinematic roots; see :mod:`dftl_warp.kernels.solvers.reference`.

Memory: besides the State, 96 bytes of float64 scratch per particle (positions, velocities,
predictions, multipliers, the Thomas sweep) and 8 bytes per strand. The scratch is owned by the
solver, so one solver advances one state at a time (like any solver instance here).

Precision: the computation is float64 whatever the model's precision; a float32 model stores
its State in float32, rounding the trajectory once per call. For reference-quality results build
the Model in float64 (the ``reference`` quality preset does).

Validity: SHAKE-type position solves need a step small enough that the constrained position is
reachable along the old segment directions; where it is not (a whipping tip, a root teleport)
the kernel splits the step in halves until it is. ``diagnostics()["constraint_residual"]``
reports the worst accepted residual. It is a reference, not a production solver: its cost
grows with the Newton iterations and the splits.

Elastic strands (opt-in): ``elastic=True`` or ``elastic={...}`` (the elastic solver's material
options) adds the ``elastic`` solver's bending and twist energy, masses and clamped root, with the
frames at their minimiser (:mod:`.reference_elastic`, kernel
:mod:`dftl_warp.kernels.solvers.reference_elastic`); ``drag`` (1/s) adds linear drag there. The
bending force is explicit: a step beyond ``2 / omega_max`` (the stiffest bending mode) is refused.
Without ``elastic`` the solver is exactly the chain of unit masses above.

Features: gravity and roots only (roots bound to a mesh included); a model with colliders, drag,
wind or hair-hair is refused (:func:`~dftl_warp.solvers.base.check_no_features`).
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
import warp as wp

from ..core.layout import strand_offsets
from ..kernels.solvers.reference import rattle_kernel
from .base import DEFAULT_GRAVITY, Solver, check_integer, check_no_features, check_real, register


@register
class ReferenceSolver(Solver):
    """RATTLE integrator of the inextensible chain (float64, Newton + Thomas per strand).

    Args:
        model: the :class:`~dftl_warp.core.model.Model`; free particles need non-zero rest lengths.
        gravity: acceleration (3,), m/s^2.
        tolerance: target of the relative squared-length residual ``| |d|^2/l^2 - 1 |`` (the
            Newton loop also stops once the residual stagnates at round-off).
        max_iterations: Newton iterations per step at most.
        accept: largest residual accepted before a step is split into halves (see
            :mod:`dftl_warp.kernels.solvers.reference`).
        elastic: None (default: inextensible chains of unit masses), True (human hair's elastic
            material) or a dict of the elastic solver's material options
            (:data:`~dftl_warp.solvers.reference_elastic.ELASTIC_OPTIONS`): elastic strands.
        drag: linear drag (1/s) toward still air, elastic strands only; 0 by default.
        frame_tolerance: elastic strands: the frames' Newton solve stops once its step is below
            this (rad).
        frame_iterations: elastic strands: Newton iterations of the frames per force evaluation
            at most.
    """

    name = "reference"
    options = ("tolerance", "max_iterations", "accept", "elastic", "drag", "frame_tolerance", "frame_iterations")

    def __init__(self, model, *, gravity=DEFAULT_GRAVITY, tolerance: float = 1.0e-14, max_iterations: int = 30,
                 accept: float = 1.0e-10, elastic=None, drag: float = 0.0, frame_tolerance: float = 1.0e-11,
                 frame_iterations: int = 30):
        tolerance = check_real("tolerance", tolerance)
        max_iterations = check_integer("max_iterations", max_iterations)
        accept = check_real("accept", accept)
        drag = check_real("drag", drag, inclusive=True)
        frame_tolerance = check_real("frame_tolerance", frame_tolerance)
        frame_iterations = check_integer("frame_iterations", frame_iterations)
        check_no_features(model, "reference")
        rest = model.rest_lengths.numpy()[model.layout.slot_of_point]
        starts = strand_offsets(model.counts)
        free = np.ones(rest.shape[0], dtype=bool)
        free[starts[model.counts > 0]] = False
        if np.any(rest[free] <= 0.0):
            i = int(np.flatnonzero(free & (rest <= 0.0))[0])
            s = int(np.searchsorted(starts, i, side="right")) - 1
            k = i - int(starts[s])
            raise ValueError(f"strand {s} of the model, segment {k - 1}: points {k - 1} and {k} coincide (a "
                             "zero-length segment); the reference solver needs non-zero rest lengths: remove the "
                             "coincident points, or use --solver dftl, which simulates them")
        super().__init__(model, gravity=gravity)
        self._gravity64 = wp.vec3d(*np.asarray(gravity, dtype=np.float64).reshape(3))
        self.tolerance = float(tolerance)
        self.max_iterations = int(max_iterations)
        self.accept = float(accept)
        self._kernel = rattle_kernel(model.scalar)
        n, dev = model.num_slots, model.device
        self._vectors = [wp.zeros(n, dtype=wp.vec3d, device=dev) for _ in range(3)]
        self._scalars = [wp.zeros(n, dtype=wp.float64, device=dev) for _ in range(3)]
        self._residual = wp.zeros(model.num_strands, dtype=wp.float64, device=dev)
        #: the elastic option's rest data, kernel and energy (None: chains of unit masses)
        self.elastic = None
        if not (elastic is None or isinstance(elastic, (bool, Mapping))):   # "yes": dict("yes") failed
            raise ValueError(f"elastic must be True, False, None or a dict of elastic options, got {elastic!r}")
        if elastic is not None and elastic is not False:
            from .reference_elastic import ElasticReference

            self.elastic = ElasticReference(model, self._gravity64, elastic, drag=drag,
                                            frame_tolerance=frame_tolerance, frame_iterations=frame_iterations)
        elif drag:
            raise ValueError(f"drag = {drag!r} needs elastic strands (elastic=...); the chain of unit masses has none")

    def _launch(self, state_in, state_out, control, dt, alpha_first, alpha_step, substeps):
        m = self.model
        if m.num_strands == 0:
            return
        if self.elastic is not None:
            self.elastic.check_step(dt)
            self.elastic.launch(self, state_in, state_out, control, dt, alpha_first, alpha_step, substeps)
            return
        wp.launch(
            self._kernel,
            dim=m.num_strands,
            inputs=[
                m.strand_base, m.strand_stride, m.strand_count,
                control.root_start, control.root_end, control.root_deviation_start, control.root_deviation_end,
                float(alpha_first), float(alpha_step), int(substeps),
                m.rest_lengths, self._gravity64, float(dt), self.tolerance, self.accept, self.max_iterations,
                state_in.positions, state_in.velocities,
                *self._vectors, *self._scalars, self._residual,
            ],
            outputs=[state_out.positions, state_out.velocities],
            device=m.device,
        )

    def step(self, state_in, state_out, control, dt: float, root_alpha: float = 1.0) -> None:
        """Advance ``state_in`` by ``dt`` seconds into ``state_out`` (which may be ``state_in``)."""
        self._launch(state_in, state_out, control, dt, root_alpha, 0.0, 1)

    def advance(self, state, control, dt: float, substeps: int) -> None:
        """``substeps`` steps of ``dt`` in place, roots moving linearly across them (one launch:
        the substep loop runs inside the kernel, in float64 throughout). The results are not checked
        (no read-back: :meth:`Solver.advance <dftl_warp.solvers.base.Solver.advance>`): a dt far beyond
        the stable range leaves NaN without a word."""
        self._launch(state, state, control, dt, 1.0 / substeps, 1.0 / substeps, substeps)

    def state(self):
        """A rest State; with elastic strands also the frames' warm start back at the rest frames."""
        if self.elastic is not None:
            self.elastic.reset_frames()
        return super().state()

    def energy(self, state) -> float:
        """Elastic strands: kinetic + gravitational + elastic energy (J) (:meth:`ElasticReference.energy
        <dftl_warp.solvers.reference_elastic.ElasticReference.energy>`)."""
        if self.elastic is None:
            raise ValueError("energy() in joules needs elastic strands (masses); diagnostics() gives J/kg")
        return self.elastic.energy(state)

    def diagnostics(self, state) -> dict:
        """Energy (J/kg), max stretch, max speed (m/s), and the last call's worst relative
        squared-length residual of the Newton solve (``constraint_residual``); with elastic
        strands also ``elastic_energy`` (:meth:`energy`, J) and ``frame_residual`` (the last
        call's largest final Newton step of the frames, rad)."""
        out = super().diagnostics(state)
        out["constraint_residual"] = float(self._residual.numpy().max()) if self.model.num_strands else 0.0
        if self.elastic is not None:
            out["elastic_energy"] = self.energy(state)
            out["frame_residual"] = float(self.elastic.frame_residual.numpy().max()) if self.model.num_strands else 0.0
        return out
