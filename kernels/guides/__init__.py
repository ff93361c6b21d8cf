"""Kernels of guide-driven render strands (:mod:`dftl_warp.guides`): :mod:`.deform` (guide frames,
then render strands deformed from them, one thread per strand)."""
