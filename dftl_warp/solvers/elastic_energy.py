"""The elastic solver's energy: the host diagnostic (:meth:`ElasticEnergy.energy`) and what the
energy check (:mod:`dftl_warp.simulation.monitor`, its kernel in kernels/simulation/energy.py) reads
to compute the same energy on the device (:meth:`ElasticEnergy.energy_arrays`,
:meth:`ElasticEnergy.rest_energy_per_mass`). A mixin of :class:`~dftl_warp.solvers.elastic.ElasticSolver`."""

from __future__ import annotations

import numpy as np

from . import elastic_rest


class ElasticEnergy:
    """Energy of an elastic solver's strands (kinetic, gravitational, bending and twist)."""

    def energy(self, state) -> float:
        """Kinetic + gravitational (relative to the roots) + elastic energy of all strands (J, or
        the model's units), computed on the host in float64."""
        m = self.model
        lay = m.layout
        x = m.points_from_device(state.positions, relative=False)
        v = m.points_from_device(state.velocities, relative=False)
        q = state.frames.numpy()[lay.slot_of_point].astype(np.float64)
        ghosts = np.zeros((m.num_strands, 3))
        ghosts[lay.strand_order] = state.clamps.numpy().astype(np.float64)
        turns = np.zeros((m.num_strands, 3, 3))   # the clamps' turn at the end of the frame just stepped
        turns[lay.strand_order] = self._clamp_rotation_end.numpy()
        starts = elastic_rest.strand_offsets(m.counts)
        total = 0.0
        for n, strands, grp in self._groups:
            idx = starts[strands][:, None] + np.arange(n)[None]
            F = elastic_rest.quat_to_mat(q[idx[:, :n - 1]])
            F[~grp.curved] = np.eye(3)      # straight strands: the frames carry no force (b = 0), nor twist
            total += float(grp.energy(x[idx], v[idx], F, ghosts[strands], self.gravity64, turns[strands],
                                      grp.curved).sum())
        return total

    def diagnostics(self, state) -> dict:
        """The base diagnostics plus ``elastic_energy`` (:meth:`energy`, J)."""
        out = super().diagnostics(state)
        out["elastic_energy"] = self.energy(state)
        return out

    def energy_arrays(self) -> dict:
        """The device arrays the energy check's kernel reads: the rest data per particle (slot order:
        ``mass``, ``length``, ``bend``, ``twist``, ``curvature``, ``rest_rotation``; overwritten in
        place when a rest shape is adopted, so valid at every check), and per device strand the
        clamps' authored directions (``clamp_direction``), whether a strand is curved (``curved``)
        and the clamps' turn at the end of the frame just simulated (``clamp_rotation``)."""
        out = {name: self._fields[name] for name in ("mass", "length", "bend", "twist", "curvature", "rest_rotation")}
        out.update(clamp_direction=self._clamp_direction, curved=self._curved, clamp_rotation=self._clamp_rotation_end)
        return out

    def rest_energy_per_mass(self) -> np.ndarray:
        """Per device strand: the elastic energy of the rest shape (J/kg, per unit of the strand's mean
        particle mass): the bending moments inverse statics leaves in a styled strand, which hold it
        up and which it cannot give away at rest."""
        m = self.model
        out = np.zeros(m.num_strands)
        for _, rows, grp in self._groups:
            still = np.zeros_like(grp.rest)
            frames = np.broadcast_to(np.eye(3), (grp.S, grp.N, 3, 3))
            # no gravity, no velocity, frames at rest: the bending and twist energy alone (J)
            out[rows] = grp.energy(grp.rest, still, frames, grp.ghost, np.zeros(3)) / grp.m[:, 1:].mean(axis=1)
        return out[m.layout.strand_order]
