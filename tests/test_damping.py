"""The damping study's physics (scripts/damping_study.py, docs/accuracy/damping.md).

Checked against physics: the undamped constrained swing conserves energy; a chain under linear
drag ``-m gamma v`` oscillating in one small mode is a damped harmonic oscillator, whose energy has
a closed form; DFTL is a first-order method whose numerical loss vanishes like dt.
"""

import importlib.util
from pathlib import Path

import numpy as np
import pytest

from dftl_warp.study import scenarios as sc

SCRIPT = Path(__file__).resolve().parents[1] / "scripts" / "damping_study.py"


@pytest.fixture(scope="module")
def study():
    spec = importlib.util.spec_from_file_location("damping_study", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def damped_mode_energy(t, omega, gamma):
    """E(t)/E(0) of ``q'' + gamma q' + omega^2 q = 0`` from rest at q = 1 (underdamped),
    ``E = (q'^2 + omega^2 q^2) / 2``; its average over a cycle falls as ``exp(-gamma t)``."""
    wd = np.sqrt(omega ** 2 - 0.25 * gamma ** 2)
    decay = np.exp(-0.5 * gamma * t)
    q = decay * (np.cos(wd * t) + 0.5 * gamma / wd * np.sin(wd * t))
    dq = -decay * omega ** 2 / wd * np.sin(wd * t)
    return (dq ** 2 + omega ** 2 * q ** 2) / omega ** 2


GAMMA = 2.0  # 1/s


def lowest_mode_chain(masses=10, segment=0.05, amplitude=5e-3):
    """A hanging chain displaced ``amplitude`` (m) along its lowest mode: (points, counts, omega rad/s)."""
    omega, shapes = sc.hanging_chain_modes(masses, segment)
    return sc.hanging_chain_in_mode(masses, segment, shapes[:, 0], amplitude), np.array([masses + 1]), omega[0]


def test_reference_keeps_the_energy_of_a_free_swing(study):
    # 0.2 m, 16 particles, 45 degrees, 1 s at 24 fps x 16 substeps: RATTLE conserves energy
    points, counts = study.released_strands((16,))
    energy, _ = study.simulate("reference", points, counts, substeps=16)
    ratio = energy[:, 0] / energy[0, 0]
    assert ratio[-1] >= 0.99
    assert np.abs(ratio - 1).max() < 0.01


def test_reference_with_linear_drag_decays_like_a_damped_oscillator(study):
    # a hanging chain of 10 masses started in its lowest mode (small amplitude: linear); a uniform
    # drag rate damps every mode alike (M-proportional damping), so the mode stays a damped
    # harmonic oscillator at the mode's frequency
    points, counts, omega = lowest_mode_chain()
    energy, equivalent = study.simulate("reference", points, counts, substeps=32, drag=GAMMA)
    measured = energy[:, 0] / energy[0, 0]
    t = np.arange(len(measured)) / study.FPS
    exact = damped_mode_energy(t, omega, GAMMA)
    assert equivalent == pytest.approx(GAMMA)
    assert np.abs(measured / exact - 1).max() < 0.01
    # about the cycle average exp(-gamma t), within the ripple of the kinetic/potential exchange
    assert abs(measured[-1] / np.exp(-GAMMA * t[-1]) - 1) < GAMMA / (2 * omega)


def test_dftl_drag_feature_is_the_same_linear_drag(study):
    # F.Drag(rate) on DFTL at fine steps (numerical loss ~0.5% at 1024 substeps) follows the same
    # damped oscillator: the feature's rate is the gamma of the force -m gamma v
    from dftl_warp.features import Drag

    points, counts, omega = lowest_mode_chain()
    energy, _ = study.simulate("dftl", points, counts, precision="float64", substeps=1024, features=[Drag(GAMMA)])
    measured = energy[:, 0] / energy[0, 0]
    exact = damped_mode_energy(np.arange(len(measured)) / study.FPS, omega, GAMMA)
    assert np.abs(measured / exact - 1).max() < 0.02


def test_dftl_loss_falls_to_the_reference_at_first_order(study):
    points, counts = study.released_strands((16,))
    substeps = [128, 256, 512, 1024, 2048]
    loss = []
    for k in substeps:
        energy, _ = study.simulate("dftl", points, counts, substeps=k, options={"fused": True})
        loss.append(1.0 - energy[-1, 0] / energy[0, 0])
    loss = np.array(loss)
    reference, _ = study.simulate("reference", points, counts, substeps=32)
    reference_loss = abs(1.0 - reference[-1, 0] / reference[0, 0])
    assert np.all(loss > 0) and np.all(np.diff(loss) < 0), loss  # DFTL (s = 1) only dissipates, less and less
    orders = np.log2(loss[:-1] / loss[1:])
    assert np.all((orders > 0.8) & (orders < 1.2)), orders
    slope = np.polyfit(np.log(1.0 / np.array(substeps)), np.log(loss), 1)[0]
    assert 0.85 < slope < 1.15, slope
    assert loss[-1] < 0.02 and reference_loss < 1e-3  # toward the converged swing, which keeps its energy


def test_drag_law_of_a_thin_cylinder(study):
    # Lamb's low-Re drag is linear in U up to the log: the rate F'/(m'U) at Re = 0.1 follows
    # 4 pi mu / (m' ln(7.4/Re)); above Re = 1 the fitted C_D = 1 + 10 Re^(-2/3)
    m = study.hair_mass_per_length()
    u = 0.1 * study.AIR_VISCOSITY / (study.AIR_DENSITY * study.HAIR_DIAMETER)  # Re = 0.1
    assert study.hair_drag(u) == pytest.approx(4 * np.pi * study.AIR_VISCOSITY / (m * np.log(7.4 / 0.1)), rel=1e-3)
    u = 8.0 * study.AIR_VISCOSITY / (study.AIR_DENSITY * study.HAIR_DIAMETER)  # Re = 8
    f = 0.5 * study.AIR_DENSITY * u * u * study.HAIR_DIAMETER * (1 + 10 * 8.0 ** (-2 / 3))
    assert study.hair_drag(u) == pytest.approx(f / (m * u), rel=1e-9)
    v = study.terminal_speed()
    assert study.drag_per_length(v, study.HAIR_DIAMETER) == pytest.approx(m * study.GRAVITY, rel=1e-6)
