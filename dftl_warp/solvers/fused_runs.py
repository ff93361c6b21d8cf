"""Launch geometry of the fused substeps: which strands run on chip, which pipelined, and when
fusing pays (:mod:`dftl_warp.kernels.solvers.fused`, :mod:`dftl_warp.kernels.solvers.pipelined`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..kernels.solvers.fused import fused_step_kernel

#: longest strand (vertices) the fused-substep kernels keep on chip (posterior form)
MAX_FUSED_VERTICES = 64

#: longest strand (vertices) the prior form keeps on chip; longer strands take the pipelined
#: kernel (:mod:`dftl_warp.kernels.solvers.pipelined`, any length), measured faster there on the H200
ON_CHIP_PRIOR_VERTICES = 32

#: threads per block of the pipelined CUDA kernel
PIPELINED_BLOCK = 128


def fused_pays(longest: int, substeps: int, precision: str, correction: str = "prior") -> bool:
    """Whether fused substeps beat one launch per substep for strands of at most ``longest``
    vertices, from the H200 measurements in docs/benchmarks.md (x the per-step kernel): float32
    strands of up to 32 vertices gain from 2 substeps per frame on (32 vertices: x1.65 at 2, x2.9
    at 4, x4.6 at 8; posterior x1.7 at 2); float64 strands of up to 32 vertices from 4 (x0.69 at
    2, x1.07 at 4, x1.26 at 8). One substep gains little or loses (x0.64-0.99).
    Longer strands in the prior form take the pipelined kernel, which gains from 2 substeps on
    (64 and 128 vertices: x1.3-1.4 at 2, x2.6-2.8 at 8; float64 at 64: x1.7 at 2, x2.7 at 8);
    longer posterior-form strands spill registers and do not gain."""
    if precision == "float32" and longest <= 32:
        return substeps >= 2
    if longest <= 32:
        return substeps >= 4
    return correction == "prior" and substeps >= PIPELINED_PAYS


#: substeps per frame from which the pipelined kernel beats one launch per substep (H200)
PIPELINED_PAYS = 2


def fused_capacity(count: int) -> int:
    """Capacity of the fused kernel serving strands of ``count`` vertices: a multiple of 8, so
    that few kernels serve grooms of many lengths."""
    return int(max(8, -(-int(count) // 8) * 8))


def fused_runs(strand_count, scalar, correction, longest: int = MAX_FUSED_VERTICES, scale_pushes: bool = True):
    """(kernel, first device strand, number of strands) for each run of consecutive device
    strands that share a fused kernel: its capacity, and whether they fill it exactly. Strands
    of more than ``longest`` vertices are left out (pipelined, :func:`pipelined_runs`).
    ``scale_pushes``: :func:`~dftl_warp.kernels.solvers.ftl.carried_func`."""
    keys = [(fused_capacity(c), bool(fused_capacity(c) == c)) if c <= longest else None for c in strand_count]
    runs, first = [], 0
    for s in range(1, len(keys) + 1):
        if s == len(keys) or keys[s] != keys[first]:
            if keys[first] is not None:
                runs.append((fused_step_kernel(scalar, correction, *keys[first], scale_pushes), first, s - first))
            first = s
    return runs


@dataclass(frozen=True)
class PipelinedRun:
    """Strands ``first ... first + strands - 1`` (device order) of ``count`` vertices each, whose
    particle ``i`` of strand ``first + r`` lives at
    ``base + ((r // 32) * chunk + r % 32) * strand_step + i * stride``, streamed by ``groups`` lane
    groups (:mod:`dftl_warp.kernels.solvers.pipelined`). ``chunk`` is 32 unless the layout interleaves."""

    first: int
    strands: int
    count: int
    base: int
    strand_step: int
    stride: int
    groups: int
    chunk: int = 32


def pipelined_runs(layout, longer_than: int) -> list[PipelinedRun]:
    """The runs of strands of more than ``longer_than`` vertices, one per layout group."""
    runs = []
    for count, first, size in layout.groups:
        if count <= longer_than:
            continue
        base = layout.strand_base[first:first + size]
        step = int(base[1] - base[0]) if size > 1 else 0
        stride = layout.strand_stride[first:first + size]
        chunk = layout.chunk_slots
        r = np.arange(size)
        if not (np.array_equal(base, base[0] + step * ((r // 32) * chunk + r % 32)) and (stride == stride[0]).all()):
            raise ValueError(f"layout {layout.name!r}: strands {first}..{first + size - 1} are not evenly spaced")
        # streams of a few hundred particles: fill and drain (2 substeps - 1 sweeps) stay small
        per_group = max(2, 256 // int(count))
        runs.append(PipelinedRun(first=int(first), strands=int(size), count=int(count), base=int(base[0]),
                                 strand_step=step, stride=int(stride[0]), groups=-(-int(size) // per_group),
                                 chunk=chunk))
    return runs
