"""Checks of an import's scale: a wrong ``--units`` and a head mesh in other units or axes than
the hair are valid input that nothing else notices (the stage's ``metersPerUnit`` is taken as
given, and a head far from the roots collides with nothing), so each is one warning naming the
file and what was measured (``docs/import.md``, "Errors and warnings")."""

from __future__ import annotations

import numpy as np

from ..errors import plural

#: median strand length (m) outside which --units is questioned: shorter than stubble, longer
#: than floor-length hair
HAIR_LENGTHS_M = (2e-3, 3.0)
#: strands shorter than this fraction of the median strand are named (data artefacts, most often)
SHORT_FRACTION = 0.01
#: the units named in the advice, metres per unit
UNIT_NAMES = {1.0: "m", 0.01: "cm", 0.001: "mm"}


def _name(mpu: float) -> str:
    return UNIT_NAMES.get(mpu, f"{mpu:g} m per unit")


def strand_lengths(points: np.ndarray, counts: np.ndarray) -> np.ndarray:
    """Polyline length of each strand (in the points' units)."""
    seg = np.linalg.norm(np.diff(points, axis=0), axis=1)
    starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
    within = np.ones(seg.shape[0], bool)
    within[starts[1:] - 1] = False          # segments from one strand's tip to the next root
    owner = np.repeat(np.arange(len(counts)), counts)[:-1]
    return np.bincount(owner[within], weights=seg[within], minlength=len(counts))


def units_note(source: str, points: np.ndarray, counts: np.ndarray, mpu: float, given: bool) -> str | None:
    """One warning when the strands' median length at ``mpu`` metres per unit is not a hair's
    (:data:`HAIR_LENGTHS_M`), naming the unit among m, cm and mm that gives one nearest 10 cm;
    None otherwise. ``given``: whether ``--units`` was given (else the format's default)."""
    median = float(np.median(strand_lengths(points, counts)))
    metres = median * mpu
    low, high = HAIR_LENGTHS_M
    if not np.isfinite(metres) or metres <= 0 or low <= metres <= high:
        return None
    fits = [u for u in UNIT_NAMES if low <= median * u <= high]
    best = min(fits, key=lambda u: abs(np.log(median * u / 0.1)), default=None)
    advice = (f"; in {_name(best)} it is {median * best:.3g} m: give --units {_name(best)}" if best is not None
              else "")
    origin = "--units" if given else "the format's default unit"
    return (f"{source}: the strands' median length is {median:.3g} units = {metres:.3g} m at {mpu:g} m per unit "
            f"({origin}), not a hair's ({low * 1e3:g} mm to {high:g} m){advice}")


def short_note(source: str, points: np.ndarray, counts: np.ndarray) -> str | None:
    """One warning when strands are shorter than :data:`SHORT_FRACTION` of the median strand (a
    7.5 um strand of 32 points in a public TressFX groom: its segments are a few float32 steps at
    its coordinates), naming how many and the shortest; None otherwise. They are written as read."""
    lengths = strand_lengths(points, counts)
    if lengths.size == 0:
        return None
    median = float(np.median(lengths))
    short = lengths < SHORT_FRACTION * median
    if median <= 0 or not short.any():
        return None
    i = int(np.argmin(np.where(short, lengths, np.inf)))
    return (f"{source}: {int(short.sum())} of {plural(lengths.size, 'strand')} are shorter than "
            f"{SHORT_FRACTION:.0%} of the "
            f"median strand ({median:.3g} units); the shortest, strand {i}, is {lengths[i]:.3g} units long with "
            f"{int(counts[i])} points. They are written as read: remove them if they are not hair")


def head_note(head: str, mesh_points: np.ndarray, roots: np.ndarray, share: float = 0.5) -> str | None:
    """One warning when fewer than ``share`` of the roots lie in the head mesh's bounding box
    (grown by a tenth of its diagonal on every side): a head in other units or axes than the hair,
    which the hair would never touch. None otherwise."""
    if mesh_points.shape[0] == 0 or roots.shape[0] == 0:
        return None
    lo, hi = mesh_points.min(axis=0), mesh_points.max(axis=0)
    pad = 0.1 * float(np.linalg.norm(hi - lo))
    near = np.all((roots >= lo - pad) & (roots <= hi + pad), axis=1)
    if near.mean() >= share:
        return None
    size = float(np.linalg.norm(hi - lo))
    spread = float(np.linalg.norm(roots.max(axis=0) - roots.min(axis=0)))
    apart = float(np.linalg.norm(0.5 * (lo + hi) - 0.5 * (roots.max(axis=0) + roots.min(axis=0))))
    return (f"{head}: {int((~near).sum())} of {roots.shape[0]} hair roots lie outside the head mesh's bounds "
            f"(head {size:.3g} units across, roots {spread:.3g} across, centres {apart:.3g} apart): is the head "
            f"in the same units and axes as the hair? It is written as read (--units and --up-axis apply "
            f"to both), and a head away from the roots is a collider the hair never touches")
