"""CT2Hair strands (``.bin``), the layout of ``save_bin_strands`` / ``load_bin_strands`` in
facebookresearch/CT2Hair (``CT2Hair/datautils/datautils.py``). Little endian, no signature::

    int32    strand count S
    S times:
      int32    vertex count n
      float32  [n][7]: x, y, z, tangent x, y, z, label

Only positions are imported. CT2Hair's released models are in millimetres (the CT volumes'
units); the axes are those of the scan, so check ``--up-axis``. Strands with fewer than 2
vertices are dropped with a warning; CT2Hair's own loader also skips strands holding NaNs
(``--drop-nonfinite`` does the same, else they are an error).
"""

from __future__ import annotations

from . import Groom, Reader
from .usc_data import read_strand_list


def read(data: bytes, path: str) -> Groom:
    return read_strand_list(data, path, 7, "CT2Hair .bin")


READER = Reader("ct2hair", (".bin",), read, meters_per_unit=0.001, up_axis="Y",
                description="CT2Hair strands (.bin)")
