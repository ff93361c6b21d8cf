"""The elastic solver's material in *stage units*: a bound curve-deformable physics material (plain
data read by :mod:`dftl_warp.usd.material`), or human hair's SI defaults converted.

UsdPhysics units: a stage length unit is ``u = metersPerUnit`` m and a stage mass unit is
``k = kilogramsPerUnit`` kg (time stays seconds). A quantity of SI dimension kg^a m^b s^c is worth
``value_SI / (k^a u^b)`` stage units:

- Young's and shear modulus (Pa = kg m^-1 s^-2): ``E_stage = E_Pa * u / k``;
- density (kg m^-3): ``rho_stage = rho * u^3 / k``;
- bend and twist stiffness E*I, G*J (N m^2 = kg m^3 s^-2): ``EI_stage = EI / (k u^3)``;
- radius (m): ``r_stage = r / u``.

Only ratios such as E / rho enter the motion, so ``kilogramsPerUnit`` changes no trajectory; it
matters for the values a user authors.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .elastic import DEFAULT_RADIUS, HAIR_DENSITY, HAIR_E, HAIR_G, TWIST_G

#: the solver's twist modulus over the material's shear modulus (a modelling choice: elastic.py)
TWIST_FACTOR = TWIST_G / HAIR_G


@dataclass
class StageMaterial:
    """A prim's elastic material in stage units. ``source``: ``"bound material PATH"`` or
    ``"defaults (human hair, Robbins 2002)"``; ``notes``: approximations to warn about."""

    youngs_modulus: float
    density: float
    shear_modulus: float
    source: str
    #: E*I override (stage units), or None
    bend_stiffness: float | None = None
    #: G*J override (stage units), or None
    twist_stiffness: float | None = None
    notes: list = field(default_factory=list)

    def twist_modulus(self, radius) -> float:
        """The solver's ``twist_modulus``: :data:`TWIST_FACTOR` x the material's G (from G*J over the
        mean polar moment when ``physics:curvesTwistStiffness`` is authored)."""
        g = self.shear_modulus
        if self.twist_stiffness is not None:
            r = float(np.mean(radius))
            g = self.twist_stiffness / (math.pi * r ** 4 / 2)
        return TWIST_FACTOR * g

    def bend_scale(self, radius) -> np.ndarray | float:
        """The factor on E*pi*r^4/4 per point that an authored E*I override needs (1 without one)."""
        if self.bend_stiffness is None:
            return 1.0
        return self.bend_stiffness / (self.youngs_modulus * math.pi * np.asarray(radius, float) ** 4 / 4)

    def bending_length(self, radius: float, gravity: float) -> float:
        """l_b = (EI / (rho A g))^(1/3) in stage units for a hair of ``radius`` under ``gravity``
        (both stage units)."""
        ei = self.bend_stiffness if self.bend_stiffness is not None else self.youngs_modulus * math.pi * radius ** 4 / 4
        w = self.density * math.pi * radius ** 2 * gravity
        return (ei / w) ** (1.0 / 3.0) if w > 0 else math.inf


DEFAULTS_SOURCE = "defaults (human hair, Robbins 2002)"


def stage_material(material, meters_per_unit: float, kilograms_per_unit: float = 1.0) -> StageMaterial:
    """The :class:`StageMaterial` of a ``CurveMaterial`` (None: the defaults) in a stage of these units."""
    u, k = float(meters_per_unit), float(kilograms_per_unit)
    E0, rho0, G0 = HAIR_E * u / k, HAIR_DENSITY * u ** 3 / k, HAIR_G * u / k
    if material is None:
        return StageMaterial(E0, rho0, G0, DEFAULTS_SOURCE)
    E = material.youngs_modulus if material.youngs_modulus is not None else E0
    rho = material.density if material.density is not None else rho0
    notes = []
    if material.poissons_ratio is not None:
        G = E / (2.0 * (1.0 + material.poissons_ratio))
    else:
        G = E * HAIR_G / HAIR_E
    if material.poissons_ratio is not None or material.twist_stiffness is not None:
        notes.append(f"{material.path}: the elastic solver's frame twist uses {TWIST_FACTOR:g} x the material's "
                     "shear modulus (a stabilising modelling choice, docs/usd.md)")
    if material.twist_stiffness is not None:
        notes.append(f"{material.path}: physics:curvesTwistStiffness is turned into one shear modulus per prim "
                     "over the mean hair radius")
    return StageMaterial(E, rho, G, f"bound material {material.path}",
                         bend_stiffness=material.bend_stiffness, twist_stiffness=material.twist_stiffness,
                         notes=notes)


def default_radius(meters_per_unit: float) -> float:
    """The solver's default hair radius (40 um) in stage units."""
    return DEFAULT_RADIUS / float(meters_per_unit)
