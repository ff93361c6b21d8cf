"""AMD TressFX binary ``.tfx`` (TressFX 3/4), the ``TressFXTFXFileHeader`` of AMD's
``TressFXFileFormat.h`` (GPUOpen-Effects/TressFX). Little endian::

    offset  0  float32   version
            4  uint32    numHairStrands
            8  uint32    numVerticesPerStrand (the same for every strand)
           12  uint32    offsetVertexPosition    float4[numHairStrands * numVerticesPerStrand]
           16  uint32    offsetStrandUV          float2[numHairStrands], 0 if none
           20  uint32    offsetVertexUV          float2[...], 0 if none
           24  uint32    offsetStrandThickness   float[numHairStrands], 0 if none
           28  uint32    offsetVertexColor       float4[...], 0 if none
           32  uint32    reserved[32]
          160  (arrays, at the offsets above, from the start of the file)

Positions are xyz plus w, where w = 0 marks an immovable vertex (the root; others are warned
about: only the root is pinned, :func:`pin_notes`). The per-strand
thickness is a multiplier of the renderer's fibre radius, not a width, so it is not imported
(``--width`` applies). The format has no unit: AMD's own sample (Ratboy) is in metres, Y up,
which are the defaults; other exports (e.g. the Sintel sample, in Blender units ~ cm) need
``--units``. The older ASCII ``.tfx`` of TressFX 1/2 is not supported.

The header describes the whole file: AMD's loader reads each array at its offset, and the exporters
(AMD's Maya and Blender ones) write the header then exactly the arrays it gives offsets for (the
Ratboy sample ends where its strand UVs do). Bytes after the last declared array are therefore an
error naming the offset where they start, as in ``.data``, ``.bin`` and PLY: the header's counts
are wrong (whole strands more than ``numHairStrands`` says, usually), and importing only the
declared strands would drop hair without a word. A declared array cut short is an error too.
"""

from __future__ import annotations

import math

import numpy as np

from ..errors import plural
from . import Groom, Reader
from ._binary import Buffer

HEADER_SIZE = 160

#: the arrays the header may declare: (offset of the field in the header, its name, what the array
#: holds, bytes per strand, bytes per vertex); the positions are always there, the others when not 0
ARRAYS = (
    (12, "offsetVertexPosition", "float4 positions", 0, 16),
    (16, "offsetStrandUV", "float2 strand UVs", 8, 0),
    (20, "offsetVertexUV", "float2 vertex UVs", 0, 8),
    (24, "offsetStrandThickness", "float strand thicknesses", 4, 0),
    (28, "offsetVertexColor", "float4 vertex colours", 0, 16),
)


def read(data: bytes, path: str) -> Groom:
    buf = Buffer(data, path)
    if data[:7].lower() in (b"version", b"numstra") or data[:1] == b"#":
        raise buf.error(0, "an ASCII TressFX 1/2 file; only the binary .tfx of TressFX 3/4 is supported")
    buf.need(0, HEADER_SIZE, "the 160-byte TressFX header")
    version, = buf.unpack("<f", 0, "header")
    strands, per_strand, *offsets = buf.unpack("<7I", 4, "header")
    off_pos, off_thick = offsets[0], offsets[3]
    if not (math.isfinite(version) and 1.0 <= version < 100.0):
        raise buf.error(0, f"version {version:g} is not a TressFX version number: not a binary .tfx file")
    if per_strand < 2:
        raise buf.error(8, f"numVerticesPerStrand = {per_strand}: a strand needs at least 2 vertices")
    if off_pos < HEADER_SIZE or off_pos % 4:
        raise buf.error(12, f"offsetVertexPosition = {off_pos}: expected a multiple of 4 at or after the "
                            f"{HEADER_SIZE}-byte header")
    total = strands * per_strand
    if off_pos + 16 * total > buf.size:
        raise buf.error(off_pos, f"truncated: {plural(strands, 'strand')} x {per_strand} vertices need "
                                 f"{16 * total} bytes "
                                 f"of float4 positions, the file has {max(buf.size - off_pos, 0)} left "
                                 f"(file size {buf.size})")
    check_extent(buf, offsets, strands, per_strand)
    xyzw = buf.array("<f4", 4 * total, off_pos, "positions").reshape(-1, 4)
    points = xyzw[:, :3].astype(np.float64)
    counts = np.full(strands, per_strand, dtype=np.int64)
    warnings = pin_notes(xyzw[:, 3].reshape(strands, per_strand), path)
    if off_thick:
        warnings.append(f"{path}: per-strand thickness is a renderer scale, not a width; not imported")
    others = [what for (field, name, what, _, _), offset in zip(ARRAYS, offsets) if offset and field not in (12, 24)]
    if others:
        warnings.append(f"{path}: not imported: {', '.join(others)} (only positions are imported)")
    return Groom(points, counts, warnings=warnings)


def pin_notes(inverse_mass: np.ndarray, path: str) -> list:
    """One warning when vertices other than the roots are immovable (w = 0, the (strands,
    per_strand) ``inverse_mass``): dftl-warp pins each strand's root, vertex 0, alone (a curve has
    no way to pin others), so they simulate free."""
    extra = inverse_mass[:, 1:] == 0
    if not extra.any():
        return []
    strand, vertex = (int(i) for i in np.argwhere(extra)[0])
    n_strands, n_vertices = int(extra.any(axis=1).sum()), int(extra.sum())
    return [f"{path}: {plural(n_strands, 'strand')} of {len(inverse_mass)} pin more than the root: "
            f"{plural(n_vertices, 'vertex', 'vertices')} after vertex 0 have w = 0 (immovable; first: strand "
            f"{strand}, vertex {vertex + 1}); only each strand's root is pinned, the others move freely"]


def check_extent(buf, offsets, strands: int, per_strand: int) -> None:
    """Every array the header declares (``offsets``: the five offset fields) lies in the file, and
    the file ends where the last of them does; otherwise an error naming the offset."""
    last, end = None, HEADER_SIZE
    for (field, name, what, per_s, per_v), offset in zip(ARRAYS, offsets):
        if offset == 0 and field != 12:
            continue
        size = strands * per_s + strands * per_strand * per_v
        if offset + size > buf.size:
            raise buf.error(offset, f"truncated: {name} (header offset {field}) declares {what} of {size} bytes, "
                                    f"the file has {max(buf.size - offset, 0)} left (file size {buf.size})")
        if offset + size >= end:
            last, end = name, offset + size
    if end < buf.size:
        extra = buf.size - end
        why = "the header's counts and offsets do not add up"
        if last == "offsetVertexPosition" and extra % (16 * per_strand) == 0:
            why = (f"the size of {extra // (16 * per_strand)} more strand(s) of {per_strand} vertices; "
                   f"numHairStrands (offset 4) says {strands}")
        raise buf.error(end, f"{extra} bytes after the last array the header declares (at {last}, which ends "
                             f"here): {why}")


READER = Reader("tfx", (".tfx",), read, meters_per_unit=1.0, up_axis="Y",
                description="AMD TressFX binary .tfx (TressFX 3/4)")
