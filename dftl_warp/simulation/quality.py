"""Quality presets: documented combinations of solver, substeps and precision.

``--quality draft|production|reference`` picks one. Each is the cheapest setting on the measured
speed-accuracy front (``dftl-warp study --front``: docs/accuracy-h200/front.md, 100k strands x 32
particles swinging under gravity, NVIDIA H200, 2026-11-24) whose error meets the preset's target
and that a preset can express; the error is the max over 12 frames of the RMS position error over
the strand length against the float64 reference solver at 64 substeps per frame.

Substeps are per frame at the scene's frame rate (24 fps: 1 substep = 41.7 ms).

- ``draft`` (target 0.25 L: the swing is there, with the right sense and roughly its amplitude):
  DFTL s = 1, prior form, 16 substeps, float32; measured 0.182 L, 0.292 ms/frame.
- ``production`` (target 0.03 L: one segment of a 32-particle strand, below the groom's own
  resolution): DFTL s = 1, prior form, 256 substeps, float32; measured 0.0169 L, 2.11 ms/frame.
- ``reference`` (target 0.001 L: a few hair diameters on a 20 cm strand): the second-order
  inextensible RATTLE solver (``rattle``), 16 substeps, float32; measured 2.6e-4 L, 11.5 ms/frame.

The presets were measured on chains (prims without bending). A prim that runs the elastic solver
(a BasisCurves prim with widths and no solver set: docs/elastic.md) keeps it under a preset and
takes the preset's substeps and precision; the elastic solver is not on the front yet, so its
error under a preset is not measured (the run says so in a start note).
"""

from __future__ import annotations

QUALITY_PRESETS = {
    "draft": {"solver": "dftl", "damping": 1.0, "correction": "prior", "substeps": 16, "precision": "float32"},
    "production": {"solver": "dftl", "damping": 1.0, "correction": "prior", "substeps": 256, "precision": "float32"},
    "reference": {"solver": "rattle", "substeps": 16, "precision": "float32"},
}

#: what each preset measured on the front (docs/accuracy-h200/front.md): error / strand length, ms/frame
#: for 100k strands x 32 particles on one NVIDIA H200
QUALITY_MEASURED = {
    "draft": (0.182, 0.292),
    "production": (0.0169, 2.11),
    "reference": (2.64e-4, 11.5),
}


def quality_preset(name: str) -> dict:
    """A copy of the preset ``name`` (keys: solver, substeps, precision and, for DFTL, damping
    and correction)."""
    if name not in QUALITY_PRESETS:
        raise ValueError(f"unknown quality {name!r}; choose one of {', '.join(QUALITY_PRESETS)}")
    return dict(QUALITY_PRESETS[name])


def preset_settings(name: str) -> dict:
    """The preset ``name`` less its solver: what a command line or a batch job fills in where it
    leaves a setting unset. The solver goes through ``quality`` (:class:`~dftl_warp.simulation.settings.SimulationOptions`): the
    prims that would run the plain chain take it, those running the elastic solver keep theirs."""
    return {k: v for k, v in quality_preset(name).items() if k != "solver"}


def describe_quality(preset, overrides: dict | None = None) -> str:
    """The line ``--quality`` prints: what the preset ``preset`` (a name, or its dict) chose and,
    for a named preset, what it measured, e.g. ``dftl-warp: quality production: solver dftl, 256
    substeps per frame, float32, damping 1, prior correction; measured 0.0169 of the strand length,
    2.11 ms/frame (...)``. ``overrides`` (option name -> value given explicitly, None = not given)
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
    line = f"dftl-warp: {label}: {', '.join(parts)}"
    if name in QUALITY_MEASURED and not given:  # an override leaves the measured setting
        error, ms = QUALITY_MEASURED[name]
        line += (f"; measured {error:.3g} of the strand length (RMS), {ms:g} ms/frame for 100k strands x 32 "
                 f"on an H200 (docs/accuracy-h200/front.md)")
    return line
