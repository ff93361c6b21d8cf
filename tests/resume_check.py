"""A Simulation's save_state / load_state round trip (not a test module)."""

from __future__ import annotations

import numpy as np


def assert_resumes_exactly(scene, options, before: int, after: int, keys=()) -> None:
    """Advance ``before`` frames, save, load the saved state into a new Simulation, and advance
    both ``after`` frames: their samples must be equal bit for bit; ``keys`` must be saved."""
    from dftl_warp.simulation.simulate import Simulation

    a = Simulation(scene, options, 1)
    for _ in range(before):
        a.advance()
    saved = a.save_state()
    assert set(keys) <= set(saved), sorted(saved)
    b = Simulation(scene, options, 1)
    b.load_state(saved)
    for _ in range(after):
        a.advance()
        b.advance()
    assert np.array_equal(a.samples()[0][0], b.samples()[0][0])
