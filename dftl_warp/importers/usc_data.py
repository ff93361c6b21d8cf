"""USC-HairSalon ``.data`` strands (Hu et al., "Single-View Hair Modeling Using A Hairstyle
Database", SIGGRAPH 2015), the layout read by the dataset's own loaders and by
CT2Hair's ``load_usc_data_strands``. Little endian, no header or signature::

    int32    strand count S
    S times:
      int32    vertex count n
      float32  xyz[n][3]

Single-vertex (and empty) strands are common in the dataset (scalp samples without hair); they
are dropped with one warning giving their count. The file must end exactly after the last strand.
The dataset's coordinates are metres, Y up (its head model stands at y ~ 1.5-1.8).
"""

from __future__ import annotations

import struct

import numpy as np

from ..errors import plural
from . import Groom, Reader
from ._binary import Buffer


def read_strand_list(data: bytes, path: str, floats_per_vertex: int, name: str) -> Groom:
    """Shared by ``.data`` (3 floats per vertex) and CT2Hair ``.bin`` (7 floats per vertex; the
    first 3 are the position)."""
    buf = Buffer(data, path)
    count, = buf.unpack("<i", 0, "the strand count")
    if count < 0:
        raise buf.error(0, f"strand count {count} is negative")
    stride = 4 * floats_per_vertex
    # every strand takes at least 4 bytes: a count above that bound cannot fit
    if 4 + 4 * count > buf.size:
        raise buf.error(0, f"strand count {count} cannot fit in a file of {buf.size} bytes")
    offsets = np.empty(count, dtype=np.int64)
    counts = np.empty(count, dtype=np.int64)
    offset = 4
    unpack = struct.Struct("<i").unpack_from
    size = buf.size
    for k in range(count):
        if offset + 4 > size:
            raise buf.error(offset, f"truncated: strand {k} of {count}: no vertex count (file size {size})")
        n, = unpack(data, offset)
        if n < 0:
            raise buf.error(offset, f"strand {k}: vertex count {n} is negative")
        offset += 4
        if offset + n * stride > size:
            raise buf.error(offset, f"truncated: strand {k} of {count}: {n} vertices need {n * stride} bytes, "
                                    f"the file has {size - offset} left (file size {size})")
        offsets[k] = offset
        counts[k] = n
        offset += n * stride
    if offset != size:
        raise buf.error(offset, f"{size - offset} bytes after the last of {plural(count, 'strand')}: the counts do not "
                                f"add up (is this really a {name} file?)")
    keep = counts >= 2
    warnings = []
    dropped = int(count - keep.sum())
    if dropped:
        warnings.append(f"{path}: dropped {dropped} of {plural(count, 'strand')} with fewer than 2 vertices")
    offsets, counts = offsets[keep], counts[keep]
    total = int(counts.sum())
    # byte offset of every kept vertex, then gather the xyz floats
    first = np.repeat(offsets - np.concatenate([[0], np.cumsum(counts)[:-1]]) * stride, counts)
    vert = first + np.arange(total, dtype=np.int64) * stride
    # every offset is a multiple of 4 (counts are int32, strides whole float32s)
    floats = np.frombuffer(data, dtype="<f4", count=size // 4)
    points = floats[(vert // 4)[:, None] + np.arange(3)].astype(np.float64) if total else np.zeros((0, 3))
    return Groom(points, counts, warnings=warnings)


def read(data: bytes, path: str) -> Groom:
    return read_strand_list(data, path, 3, "USC-HairSalon .data")


READER = Reader("data", (".data",), read, meters_per_unit=1.0, up_axis="Y",
                description="USC-HairSalon strands (.data)")
