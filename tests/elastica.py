"""The large-deflection elastica of a horizontal cantilever under its own weight, the statics tests'
analytic reference."""

from __future__ import annotations

import numpy as np


def cantilever(L, s_eval, ei, w):
    """(x, y) at arc lengths ``s_eval`` of a cantilever of length ``L`` (m), bending stiffness ``ei``
    (N m^2) and weight per length ``w`` (N/m): EI th'' = -w (L - s) cos th, th(0) = 0, th'(L) = 0
    (scipy ``solve_bvp``, continuation in the load)."""
    from scipy.integrate import cumulative_trapezoid, solve_bvp

    s = np.linspace(0, L, 401)
    guess = np.zeros((2, s.size))
    for frac in np.linspace(0.1, 1.0, 10):
        sol = solve_bvp(lambda s, y, q=w * frac: np.vstack([y[1], -q * (L - s) * np.cos(y[0]) / ei]),
                        lambda a, b: np.array([a[0], b[1]]), s, guess, tol=1e-10, max_nodes=100000)
        guess = sol.sol(s)
    assert sol.success, sol.message
    sf = np.linspace(0, L, 20001)
    th = sol.sol(sf)[0]
    xs = cumulative_trapezoid(np.cos(th), sf, initial=0.0)
    ys = -np.abs(cumulative_trapezoid(np.sin(th), sf, initial=0.0))
    return np.interp(s_eval, sf, xs), np.interp(s_eval, sf, ys)
