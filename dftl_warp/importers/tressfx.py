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

Positions are xyz plus w, where w = 0 marks an immovable vertex (the root). The per-strand
thickness is a multiplier of the renderer's fibre radius, not a width, so it is not imported
(``--width`` applies). The format has no unit: AMD's own sample (Ratboy) is in metres, Y up,
which are the defaults; other exports (e.g. the Sintel sample, in Blender units ~ cm) need
``--units``. The older ASCII ``.tfx`` of TressFX 1/2 is not supported.
"""

from __future__ import annotations

import math

import numpy as np

from . import Groom, Reader
from ._binary import Buffer

HEADER_SIZE = 160


def read(data: bytes, path: str) -> Groom:
    buf = Buffer(data, path)
    if data[:7].lower() in (b"version", b"numstra") or data[:1] == b"#":
        raise buf.error(0, "an ASCII TressFX 1/2 file; only the binary .tfx of TressFX 3/4 is supported")
    buf.need(0, HEADER_SIZE, "the 160-byte TressFX header")
    version, = buf.unpack("<f", 0, "header")
    strands, per_strand, off_pos, _suv, _vuv, off_thick, _col = buf.unpack("<7I", 4, "header")
    if not (math.isfinite(version) and 1.0 <= version < 100.0):
        raise buf.error(0, f"version {version:g} is not a TressFX version number: not a binary .tfx file")
    if per_strand < 2:
        raise buf.error(8, f"numVerticesPerStrand = {per_strand}: a strand needs at least 2 vertices")
    if off_pos < HEADER_SIZE or off_pos % 4:
        raise buf.error(12, f"offsetVertexPosition = {off_pos}: expected a multiple of 4 at or after the "
                            f"{HEADER_SIZE}-byte header")
    total = strands * per_strand
    if off_pos + 16 * total > buf.size:
        raise buf.error(off_pos, f"truncated: {strands} strands x {per_strand} vertices need {16 * total} bytes "
                                 f"of float4 positions, the file has {max(buf.size - off_pos, 0)} left "
                                 f"(file size {buf.size})")
    xyzw = buf.array("<f4", 4 * total, off_pos, "positions").reshape(-1, 4)
    points = xyzw[:, :3].astype(np.float64)
    counts = np.full(strands, per_strand, dtype=np.int64)
    warnings = []
    if off_thick:
        warnings.append(f"{path}: per-strand thickness is a renderer scale, not a width; not imported")
    return Groom(points, counts, warnings=warnings)


READER = Reader("tfx", (".tfx",), read, meters_per_unit=1.0, up_axis="Y",
                description="AMD TressFX binary .tfx (TressFX 3/4)")
