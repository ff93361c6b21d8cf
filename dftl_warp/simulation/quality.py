"""Quality presets: documented combinations of solver, substeps and precision.

``--quality draft|production|reference`` picks one; the accuracy study (docs/accuracy.md,
"Quality presets") measures each one's error against the reference and its cost.

Substeps are per frame at the scene's frame rate (24 fps: 1 substep = 41.7 ms).

- ``draft``: DFTL s = 1, one substep per frame, float32. Unconditionally stable and
  inextensible, but heavily damped (strands settle within a few frames and barely swing):
  for blocking and previews.
- ``production``: DFTL s = 1, 16 substeps per frame (2.6 ms at 24 fps), float32: the fewest
  substeps at which the study's groom on a moving head stays within 10 % of the strand length
  (RMS, first 0.5 s) of the true dynamics, with lengths exact and no tuning; 16 kernel launches
  per frame (one CUDA graph on the GPU). float32 suffices: its round-off floor (~3e-3 of the
  length on the falling chain) is far below the discretisation error at these steps.
- ``reference``: the RATTLE reference solver (true inextensible-chain dynamics, second order),
  64 substeps per frame (0.65 ms), float64: for validation and look-development of final shots;
  an order of magnitude slower.
"""

from __future__ import annotations

QUALITY_PRESETS = {
    "draft": {"solver": "dftl", "damping": 1.0, "correction": "prior", "substeps": 1, "precision": "float32"},
    "production": {"solver": "dftl", "damping": 1.0, "correction": "prior", "substeps": 16, "precision": "float32"},
    "reference": {"solver": "reference", "substeps": 64, "precision": "float64"},
}


def quality_preset(name: str) -> dict:
    """A copy of the preset ``name`` (keys: solver, substeps, precision and, for DFTL, damping
    and correction)."""
    if name not in QUALITY_PRESETS:
        raise ValueError(f"unknown quality {name!r}; choose one of {', '.join(QUALITY_PRESETS)}")
    return dict(QUALITY_PRESETS[name])


def describe_quality(preset, overrides: dict | None = None) -> str:
    """The line ``--quality`` prints: what the preset ``preset`` (a name, or its dict) chose,
    e.g. ``dftl-warp: quality production: solver dftl, 16 substeps per frame, float32, damping 1,
    prior correction``. ``overrides`` (option name -> value given explicitly, None = not given)
    are shown where they replace the preset's part."""
    name = preset if isinstance(preset, str) else None
    values = quality_preset(preset) if isinstance(preset, str) else dict(preset)
    given = {k: v for k, v in (overrides or {}).items() if v is not None and k in values and v != values[k]}

    def part(key, text):
        if key in given:
            return f"{text(given[key])} (given; the preset has {text(values[key])})"
        return text(values[key])

    parts = [part("solver", lambda v: f"solver {v}"),
             part("substeps", lambda v: f"{v} substep{'s' if int(v) != 1 else ''} per frame"),
             part("precision", str)]
    if "damping" in values:
        parts.append(part("damping", lambda v: f"damping {float(v):g}"))
    if "correction" in values:
        parts.append(part("correction", lambda v: f"{v} correction"))
    label = f"quality {name}" if name else "quality"
    return f"dftl-warp: {label}: {', '.join(parts)}"
