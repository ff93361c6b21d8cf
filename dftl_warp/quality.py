"""Quality presets: documented combinations of solver, substeps and precision.

``--quality draft|production|reference`` picks one; the accuracy study (docs/accuracy.md,
"Quality presets") measures each one's error against the reference and its cost.

Substeps are per frame at the scene's frame rate (24 fps: 1 substep = 41.7 ms).

- ``draft``: DFTL s = 1, one substep per frame, float32. Unconditionally stable and
  inextensible, but heavily damped (strands settle within a few frames and barely swing):
  for blocking and previews.
- ``production``: DFTL s = 1, 8 substeps per frame (5.2 ms at 24 fps), float32. First-order
  convergence makes each doubling of substeps halve the error; at 8 the groom's error is a few
  percent of the strand length while a frame still costs one kernel launch per substep (a
  CUDA graph on the GPU). float32 suffices: its round-off floor (~1e-6 of the strand length)
  is far below the discretisation error at these steps.
- ``reference``: the RATTLE reference solver (true inextensible-chain dynamics, second order),
  64 substeps per frame (0.65 ms), float64: for validation and look-development of final shots;
  an order of magnitude slower.
"""

from __future__ import annotations

QUALITY_PRESETS = {
    "draft": {"solver": "dftl", "damping": 1.0, "correction": "prior", "substeps": 1, "precision": "float32"},
    "production": {"solver": "dftl", "damping": 1.0, "correction": "prior", "substeps": 8, "precision": "float32"},
    "reference": {"solver": "reference", "substeps": 64, "precision": "float64"},
}


def quality_preset(name: str) -> dict:
    """A copy of the preset ``name`` (keys: solver, substeps, precision and, for DFTL, damping
    and correction)."""
    if name not in QUALITY_PRESETS:
        raise ValueError(f"unknown quality {name!r}; choose one of {', '.join(QUALITY_PRESETS)}")
    return dict(QUALITY_PRESETS[name])
