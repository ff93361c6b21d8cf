"""Cem Yuksel's HAIR format (``.hair``), as defined by ``cyHairFile.h``
(http://www.cemyuksel.com/research/hairmodels/).

Layout, little endian::

    offset  0  char[4]   "HAIR"
            4  uint32    hair_count (strands)
            8  uint32    point_count (all strands)
           12  uint32    arrays: bit 0 segments, 1 points, 2 thickness, 3 transparency, 4 colors
           16  uint32    d_segments (segments per strand when there is no segments array)
           20  float32   d_thickness
           24  float32   d_transparency
           28  float32   d_color[3]
           40  char[88]  file information
          128  uint16    segments[hair_count]            (if bit 0)
               float32   points[point_count][3]          (if bit 1)
               float32   thickness[point_count]          (if bit 2)
               float32   transparency[point_count]       (if bit 3)
               float32   color[point_count][3]           (if bit 4)

A strand of s segments has s + 1 points. Thickness is the strand's diameter, in the units of the
points; it becomes the USD ``widths`` (per vertex with the thickness array, else constant
``d_thickness``, which must then be finite and >= 0; 0 means none). Strands of 0 segments (one
point) are dropped with a warning, as in the other formats. Transparency and colors are not
imported (one warning names them). The format has no unit; its models are Z-up.
"""

from __future__ import annotations

import numpy as np

from ..errors import plural
from . import Groom, Reader
from ._binary import Buffer, drop_short_strands

SEGMENTS_BIT, POINTS_BIT, THICKNESS_BIT, TRANSPARENCY_BIT, COLORS_BIT = 1, 2, 4, 8, 16
HEADER_SIZE = 128


def read(data: bytes, path: str) -> Groom:
    buf = Buffer(data, path)
    buf.need(0, HEADER_SIZE, "the 128-byte HAIR header")
    if data[:4] != b"HAIR":
        raise buf.error(0, f"signature {data[:4]!r} is not b'HAIR': not a HAIR file")
    hair_count, point_count, arrays, d_segments = buf.unpack("<4I", 4, "header")
    d_thickness, = buf.unpack("<f", 20, "header")
    warnings = []
    if arrays & ~0x1F:
        warnings.append(f"{path}: unknown array bits 0x{arrays & ~0x1F:x} in the header; ignored")
    if not arrays & POINTS_BIT:
        raise buf.error(12, f"arrays = 0x{arrays:x} has no points array (bit 1)")
    offset = HEADER_SIZE
    if arrays & SEGMENTS_BIT:
        segments = buf.array("<u2", hair_count, offset,
                             f"segments array of {plural(hair_count, 'strand')}").astype(np.int64)
        seg_offset = offset
        offset += 2 * hair_count
    else:
        # no per-strand array: check the total before allocating one entry per (claimed) strand
        if hair_count * (d_segments + 1) != point_count:
            raise buf.error(16, f"d_segments gives {hair_count * (d_segments + 1)} points for "
                                f"{plural(hair_count, 'strand')} "
                                f"but the header says point_count = {point_count}")
        buf.need(offset, 12 * point_count, f"points array of {point_count} points")
        segments = np.full(hair_count, d_segments, dtype=np.int64)
        seg_offset = 16
    counts = segments + 1
    total = int(counts.sum())
    if total != point_count:
        where = "segments array" if arrays & SEGMENTS_BIT else "d_segments"
        raise buf.error(seg_offset, f"{where} gives {total} points for {plural(hair_count, 'strand')} "
                                    f"but the header says point_count = {point_count}")
    points = buf.array("<f4", 3 * point_count, offset, f"points array of {point_count} points")
    with np.errstate(invalid="ignore"):   # corrupted bytes may be signalling NaNs (convert.py: check_finite)
        points = points.reshape(-1, 3).astype(np.float64)
    offset += 12 * point_count
    widths = None
    constant = None
    if arrays & THICKNESS_BIT:
        widths = buf.array("<f4", point_count, offset, f"thickness array of {point_count} points").astype(np.float64)
        bad = ~np.isfinite(widths) | (widths < 0)
        if bad.any():
            i = int(np.flatnonzero(bad)[0])
            raise buf.error(offset + 4 * i, f"thickness[{i}] = {widths[i]:g}: expected a finite number >= 0")
        offset += 4 * point_count
    elif not (np.isfinite(d_thickness) and d_thickness >= 0):
        raise buf.error(20, f"d_thickness (the header's default thickness) = {d_thickness:g}: expected a finite "
                            f"number >= 0 (there is no thickness array)")
    elif d_thickness > 0:
        constant = float(d_thickness)
    if arrays & THICKNESS_BIT and not (np.isfinite(d_thickness) and d_thickness >= 0):
        warnings.append(f"{path}: offset 20: d_thickness (the header's default thickness) = {d_thickness:g} is not a "
                        f"width; ignored (the thickness array gives the widths)")
    if arrays & TRANSPARENCY_BIT:
        buf.need(offset, 4 * point_count, f"transparency array of {point_count} points")
        offset += 4 * point_count
    if arrays & COLORS_BIT:
        buf.need(offset, 12 * point_count, f"colors array of {point_count} points")
        offset += 12 * point_count
    skipped = [name for bit, name in ((TRANSPARENCY_BIT, "transparency"), (COLORS_BIT, "colors")) if arrays & bit]
    if skipped:
        warnings.append(f"{path}: not imported: the {' and '.join(skipped)} array{'s' if len(skipped) > 1 else ''} "
                        f"(only points and thickness are imported)")
    if offset < buf.size:
        warnings.append(f"{path}: {buf.size - offset} bytes after the last array (offset {offset}); ignored")
    points, counts, widths = drop_short_strands(path, points, counts, widths, warnings)
    return Groom(points, counts, widths=widths, constant_width=constant, warnings=warnings)


READER = Reader("hair", (".hair",), read, meters_per_unit=0.01, up_axis="Z",
                description="Cem Yuksel's HAIR format (cyHairFile.h)")
