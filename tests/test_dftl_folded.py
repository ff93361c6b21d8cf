"""Folded, fast strands (docs/accuracy/folded.md): DFTL with s = 1 no longer creates energy there.

Strands folded tighter than a right angle at every joint and moving fast (as a collider leaves
them) hold their energy under the true dynamics: the RATTLE reference in float64 at a fine step
keeps it to 1e-3. With the paper's correction carried whole, DFTL with s = 1 settles at 32
substeps a frame into a thrash in which its particles move most of a segment every step and the
strands hold several times that energy (the numpy baseline with ``scale_pushes=False``). The
kernels scale a follower's push on its leader by ``max(1 - a m, 0)``, ``m`` its motion in the step
over its rest length (``kernels/solvers/ftl.py``, ``carried_func``; ``a = PUSH_MOTION_SCALE``, 1.5:
docs/accuracy/push-scale.md): from the same start their strands lose energy at
8 to 64 substeps, in both correction forms, and the monitor stays silent. The scaling vanishes as
the step shrinks: on an inverted chain, whose links push as it starts to fall, DFTL still
converges to the reference at first order, as with the paper's correction, where dropping the
pushes outright does not converge.
"""

import importlib.util
from pathlib import Path

import numpy as np
import pytest

import dftl_warp as dw
from dftl_warp.study.scenarios import folded_strands

SCRIPT = Path(__file__).resolve().parents[1] / "scripts" / "probe_dftl_folded.py"
STRANDS, POINTS, SEGMENT, FPS, FRAMES = 4, 16, 0.005, 24, 8


def _script(name: str):
    spec = importlib.util.spec_from_file_location(name, SCRIPT.with_name(f"{name}.py"))
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


PROBE = _script("probe_dftl_folded")


def run(kind, substeps):
    """Per frame and strand, the available energy (J/kg, summed over particles) and the RMS speed,
    and the strands the monitor flagged (the probe's runs, on 4 strands for 8 frames)."""
    positions, velocities = folded_strands(STRANDS, POINTS, SEGMENT, speed=0.7, seed=1)
    return PROBE.run_solver(kind, positions, velocities, STRANDS, substeps, frames=FRAMES, device="cpu")


@pytest.fixture(scope="module")
def true_energy():
    energies, _, flagged = run("reference", 512)
    drift = np.abs(energies / energies[0] - 1.0).max()
    assert drift < 1e-3 and not flagged.any(), drift   # the true dynamics keeps its energy
    return energies[0]


def test_the_papers_correction_thrashes_from_folded_fast_starts(true_energy):
    positions, velocities = folded_strands(STRANDS, POINTS, SEGMENT, speed=0.7, seed=1)
    energies, speeds, _ = PROBE.run_paper(positions, velocities, STRANDS, 32)
    energies, speeds = energies[:FRAMES], speeds[:FRAMES]
    assert (energies.max(axis=0) / true_energy > 3.0).all(), energies.max(axis=0) / true_energy
    # the thrash: the particles move about a segment every step (not a blow-up: the speed is bounded)
    per_step = speeds[FRAMES // 2:].mean(axis=0) / FPS / 32 / SEGMENT
    assert ((per_step > 0.5) & (per_step < 1.5)).all(), per_step


@pytest.mark.parametrize("substeps", [8, 16, 32, 64])
@pytest.mark.parametrize("correction", ["prior", "posterior"])
def test_dftl_loses_energy_from_folded_fast_starts(true_energy, substeps, correction):
    kind = "dftl" if correction == "prior" else "dftl posterior"
    energies, _, flagged = run(kind, substeps)
    # the first frames may exceed the reference's energy after its first frame (the two project
    # the start's velocity along the segments differently); from the third frame on, below it
    assert (energies[2:].max(axis=0) < true_energy).all(), energies[2:].max(axis=0) / true_energy
    assert (energies.max(axis=0) < 2.0 * true_energy).all() and not flagged.any()


def test_the_elastic_solver_loses_energy_from_the_same_start(true_energy):
    energies, _, flagged = run("elastic", 32)
    assert (energies.max(axis=0) < true_energy).all() and not flagged.any()


def inverted_chain_errors(steps_list):
    """Largest position error (over particles, relative to L) at T = 0.1 s of a 5-particle, 2 cm chain
    standing 10 degrees off upright, against RATTLE (float64, 20000 steps): the kernels' DFTL and the
    numpy DFTL with the paper's correction and with pushes dropped."""
    n, length, duration = 5, 0.02, 0.1
    tilt = np.radians(10.0)
    points = np.stack([np.linspace(0, length, n) * np.sin(tilt), np.linspace(0, length, n) * np.cos(tilt),
                       np.zeros(n)], 1)

    def kernel_run(solver_name, steps):
        model = dw.Model.from_strands(points, [n], widths=1e-4, device="cpu", precision="float64")
        solver = dw.make_solver(model, solver_name, gravity=(0.0, -9.81, 0.0))
        state, control = solver.state(), model.control()
        solver.advance(state, control, duration / steps, steps)
        return model.points_from_device(state.positions, relative=False)

    def numpy_run(steps, pulls_only):
        from dftl_warp.solvers.numpy_baseline import pad_strands, step, unpad_strands

        x = pad_strands(points, [n])
        v, c = np.zeros_like(x), np.zeros_like(x)
        rest = np.zeros((1, n))
        rest[:, 1:] = np.linalg.norm(np.diff(x, axis=1), axis=2)
        for _ in range(steps):
            x, v, c = step(x, v, c, rest, np.array([n]), x[:, 0], dt=duration / steps, gravity=(0.0, -9.81, 0.0),
                           scale_pushes=False)
            if pulls_only:
                pushed = np.einsum("sij,sij->si", c[:, 1:], x[:, 1:] - x[:, :-1]) > 0.0
                c[:, 1:][pushed] = 0.0
        return unpad_strands(x, [n])

    reference = kernel_run("reference", 20000)
    assert reference[-1, 1] < 0.0   # the chain fell past its root within the run
    error = {"kernels": [], "paper": [], "pulls only": []}
    for steps in steps_list:
        error["kernels"].append(np.abs(kernel_run("dftl", steps) - reference).max() / length)
        error["paper"].append(np.abs(numpy_run(steps, False) - reference).max() / length)
        error["pulls only"].append(np.abs(numpy_run(steps, True) - reference).max() / length)
    return {k: np.array(v) for k, v in error.items()}


def test_scaled_pushes_keep_dftls_convergence_where_links_push():
    error = inverted_chain_errors([96, 384, 1536])
    kernels, paper = error["kernels"], error["paper"]
    assert kernels[-1] < 0.01 and kernels[1] / kernels[2] > 3.5, kernels      # first order, to 1% of L
    assert np.allclose(kernels, paper, rtol=0.1), (kernels, paper)            # as the paper's correction
    assert error["pulls only"][-1] > 3.0 * kernels[-1], error                  # dropping pushes does not


@pytest.mark.parametrize("points", [16, 40])   # on-chip fused kernel; pipelined (longer than 32)
@pytest.mark.parametrize("scale_pushes", [True, False])
def test_fused_substeps_equal_the_step_kernel_on_folded_strands_bitwise(points, scale_pushes):
    """Folded, fast strands push at every step: the fused (16 points) and pipelined (40) substeps
    carry the same scaled, or whole, pushes as the per-step kernel, to the bit."""
    positions, velocities = folded_strands(3, points, SEGMENT, speed=0.7, seed=2)
    out = []
    for fused in (False, True):
        model = dw.Model.from_strands(positions, [points] * 3, widths=1e-4, device="cpu")
        solver = dw.DFTLSolver(model, gravity=(0.0, -9.81, 0.0), fused=fused, scale_pushes=scale_pushes)
        state, control = solver.state(), model.control()
        state.velocities.assign(model.points_to_device(velocities, relative=False))
        for _ in range(3):
            solver.advance(state, control, 1.0 / FPS / 8, 8)
        out.append([a.numpy().copy() for a in (state.positions, state.velocities, state.corrections)])
    for a, b in zip(*out):
        assert np.array_equal(a, b)


def test_scale_pushes_false_is_the_papers_correction():
    """``DFTLSolver(scale_pushes=False)`` runs the numpy baseline's paper form (float64, to round-off
    over 8 steps: the thrash amplifies round-off after that) and thrashes from the folded start as
    it does; the default does not."""
    from dftl_warp.solvers.numpy_baseline import pad_strands, step, unpad_strands

    positions, velocities = folded_strands(STRANDS, POINTS, SEGMENT, speed=0.7, seed=1)
    dt = 1.0 / FPS / 32
    x, v = pad_strands(positions, [POINTS] * STRANDS), pad_strands(velocities, [POINTS] * STRANDS)
    c = np.zeros_like(x)
    rest = np.zeros((STRANDS, POINTS))
    rest[:, 1:] = np.linalg.norm(np.diff(x, axis=1), axis=2)
    for _ in range(8):
        x, v, c = step(x, v, c, rest, np.full(STRANDS, POINTS), x[:, 0], dt=dt, gravity=(0.0, -9.81, 0.0),
                       scale_pushes=False)
    speeds = {}
    for scale_pushes in (False, True):
        model = dw.Model.from_strands(positions, [POINTS] * STRANDS, widths=1e-4, device="cpu", precision="float64")
        solver = dw.DFTLSolver(model, gravity=(0.0, -9.81, 0.0), scale_pushes=scale_pushes)
        state, control = solver.state(), model.control()
        state.velocities.assign(model.points_to_device(velocities, relative=False))
        solver.advance(state, control, dt, 8)
        if not scale_pushes:
            got = model.points_from_device(state.positions, relative=False)
            assert np.abs(got - unpad_strands(x, [POINTS] * STRANDS)).max() < 1e-12
        solver.advance(state, control, dt, 6 * 32 - 8)
        vel = model.points_from_device(state.velocities, relative=False)
        speeds[scale_pushes] = float(np.sqrt((vel ** 2).sum(axis=1).mean()))
    # after 6 frames at 32 substeps: the whole pushes keep the particles near a segment per step
    # (0.69 of one), the scaled ones have let them settle (0.06)
    assert speeds[False] * dt / SEGMENT > 0.4 and speeds[True] * dt / SEGMENT < 0.15, speeds


@pytest.mark.parametrize("seed, speed, substeps", [(2, 0.7, 24), (3, 1.2, 32)])
def test_the_push_scale_keeps_the_monitor_silent_on_folded_fast_strands(seed, speed, substeps):
    """Two of the starts of docs/accuracy/push-scale.md (96 strands, one second) where pushes scaled
    by max(1 - m, 0) (a = 1) still pumped strands past the energy monitor's budget (at least 4);
    with the default a = 1.5 the monitor flags at most a quarter as many (the CPU: none; the H200,
    whose float32 round-off differs: 1 against 5 at 32 substeps, docs/gpu-checks.md)."""
    from dftl_warp.kernels.solvers import ftl

    study = _script("push_scale_study")   # its use_scale rebuilds the step kernels with another a
    positions, velocities = folded_strands(96, POINTS, SEGMENT, speed=speed, seed=seed)
    flagged = {}
    default = ftl.PUSH_MOTION_SCALE
    try:
        for a in (1.0, default):
            study.use_scale(a)
            flagged[a] = int(PROBE.run_solver("dftl", positions, velocities, 96, substeps, device="cpu")[2].sum())
    finally:
        study.use_scale(default)
    assert default == 1.5 and flagged[1.0] >= 4 and flagged[default] <= flagged[1.0] // 4, flagged
