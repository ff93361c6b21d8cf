"""Hair-hair interaction in the elastic solver (CPU): friction toward the grid velocity in the
implicit solve, repulsion down the density gradient.

Friction is a force ``m c (v_grid - v)``. Where two strands share the same place and move in
opposite directions the grid velocity is zero, so each strand is a cantilever with mass-
proportional viscous damping ``c``: every bending mode's energy decays as ``exp(-c t)`` beyond
what the undamped run loses to the integrator. That ratio is the analytic check."""

from __future__ import annotations

import numpy as np
import pytest

import dftl_warp as dw
from dftl_warp import features as F
from dftl_warp.solvers.elastic import HAIR_DENSITY, HAIR_E

R = 40e-6          # 80 um hair
N = 16
FPS = 24.0
EI = HAIR_E * np.pi * R ** 4 / 4
LB = (EI / (HAIR_DENSITY * np.pi * R ** 2 * 9.81)) ** (1.0 / 3.0)   # bending length, 4.93 cm


def segment_lengths(x, counts):
    starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
    return np.concatenate([np.linalg.norm(np.diff(x[s:s + n], axis=0), axis=1) for s, n in zip(starts, counts)])


def paired_cantilevers(pairs: int = 3):
    """``pairs`` pairs of straight horizontal strands of length LB along x, the two of a pair 10 um
    apart (one place for a 1 cm grid), the pairs 3 cm apart."""
    s = np.linspace(0.0, LB, N + 1)
    strands = []
    for p in range(pairs):
        for dz in (0.0, 1e-5):
            strands.append(np.stack([s, np.zeros_like(s), np.full_like(s, 0.03 * p + dz)], 1))
    return np.concatenate(strands), np.full(2 * pairs, N + 1)


@pytest.mark.parametrize("correction", ["prior", "posterior"])
def test_friction_damps_opposed_strands_at_its_rate_and_never_adds_energy(correction):
    """Opposed velocities (+u, -u along y) in each pair: with friction c = 2/s the energy after
    T = 0.5 s is exp(-c T) of the frictionless run's (within 3%), and it never rises."""
    pts, counts = paired_cantilevers()
    substeps, frames, c, u = 32, 12, 2.0, 0.01
    signs = np.repeat(np.tile([1.0, -1.0], len(counts) // 2), N + 1)
    free = np.tile(np.r_[0.0, np.ones(N)], len(counts))
    v0 = (signs * free * u)[:, None] * np.array([0.0, 1.0, 0.0])
    energy = {}
    for friction in (0.0, c):
        model = dw.Model.from_strands(pts, counts, precision="float64",
                                      features=[F.HairHair(cell_size=0.01, friction=friction, repulsion=0.0)])
        solver = dw.make_solver(model, "elastic", radius=R, gravity=(0.0, 0.0, 0.0), correction=correction)
        state, control = solver.state(), model.control()
        state.write("velocities", model.points_to_device(v0, relative=False))
        series = [solver.energy(state)]
        for _ in range(frames):
            for _ in range(substeps):
                solver.step(state, state, control, 1.0 / (FPS * substeps), 1.0)
                series.append(solver.energy(state))
        series = np.array(series)
        assert np.diff(series).max() <= 1e-12 * series[0]          # friction and the solver only take energy
        x = model.points_from_device(state.positions)
        assert np.abs(segment_lengths(x, counts) / (LB / N) - 1).max() < 1e-12
        energy[friction] = series
    T = frames / FPS
    ratio = energy[c][-1] / energy[0.0][-1]
    assert ratio == pytest.approx(np.exp(-c * T), rel=0.03)


def test_repulsion_spreads_a_dense_bundle_of_elastic_strands():
    """A 5 x 5 bundle of hanging strands 1 mm apart, half a bending length long, on 5 mm cells:
    with repulsion (of all the density: threshold 0) their tips spread apart; without it they hang
    as authored (inverse statics).
    The repulsion, 1000 m/s^2 per unit of the density relative to the bundle's at rest, is the push
    of 50 m/s^2 per particle per node of the grid's first form (20 particles per node at rest)."""
    side, spacing, length = 5, 0.001, 0.5 * LB
    s = np.linspace(0.0, length, N + 1)
    strands = [np.stack([np.full_like(s, i * spacing), -s, np.full_like(s, j * spacing)], 1)
               for i in range(side) for j in range(side)]
    pts, counts = np.concatenate(strands), np.full(side * side, N + 1)
    tips = slice(N, None, N + 1)
    spread = {}
    for repulsion in (0.0, 1000.0):
        model = dw.Model.from_strands(pts, counts, precision="float64",
                                      features=[F.HairHair(cell_size=0.005, friction=2.0, repulsion=repulsion,
                                                           threshold=0.0)])
        solver = dw.make_solver(model, "elastic", radius=R)
        state, control = solver.state(), model.control()
        solver.advance(state, control, 1.0 / (FPS * 8), 8 * 24)
        x = model.points_from_device(state.positions)
        assert np.abs(segment_lengths(x, counts) / (length / N) - 1).max() < 1e-12
        t = x[tips][:, [0, 2]]
        spread[repulsion] = np.sqrt(np.trace(np.cov(t.T)))
    authored = np.sqrt(np.trace(np.cov(pts[tips][:, [0, 2]].T)))
    assert spread[0.0] == pytest.approx(authored, rel=1e-6)
    assert spread[1000.0] > 1.5 * authored
