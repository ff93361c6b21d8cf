"""Particle layout: where particle ``i`` of strand ``s`` lives in the device arrays.

Every per-particle device array (positions, velocities, corrections, rest lengths) uses the same
layout, described per *device strand* by two integers::

    slot(s, i) = strand_base[s] + i * strand_stride[s]

which the kernels evaluate through one helper, :func:`dftl_warp.kernels.layout.particle`.

Two layouts exist:

``"strand-major"``
    each strand's particles are contiguous (stride 1). Best for the serial CPU backend, where one
    thread walks a strand through consecutive memory.
``"particle-major"``
    strands are grouped by vertex count; inside a group of ``S`` strands, particle ``i`` of every
    strand is contiguous (stride ``S``), so neighbouring GPU threads touch neighbouring memory.
    Best on CUDA (measured in ``scripts/bench.py``; see ``docs/benchmarks.md``).

Device strands are ordered so that strands of one group are consecutive. The host keeps the
mapping back to the caller's order (:attr:`Layout.slot_of_point`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

LAYOUTS = ("strand-major", "particle-major")


def default_layout(device: str) -> str:
    """The layout measured fastest on ``device`` (``"cpu"`` or ``"cuda:N"``)."""
    return "particle-major" if str(device).startswith("cuda") else "strand-major"


@dataclass(frozen=True)
class Layout:
    """Host-side description of a particle layout (all arrays are numpy int64)."""

    name: str
    #: input strand index of each device strand (device order -> input order)
    strand_order: np.ndarray
    #: first slot of each device strand
    strand_base: np.ndarray
    #: slot distance between consecutive particles of each device strand
    strand_stride: np.ndarray
    #: vertex count of each device strand
    strand_count: np.ndarray
    #: device slot of every input point, in input order (None for device-built synthetic grooms)
    slot_of_point: np.ndarray | None
    #: (count, first device strand, number of strands) for each group of equal vertex count
    groups: tuple[tuple[int, int, int], ...]

    @property
    def num_slots(self) -> int:
        return int(self.strand_count.sum())


def make_layout(counts: np.ndarray, name: str) -> Layout:
    """Build the layout ``name`` for strands with vertex ``counts`` (input order)."""
    if name not in LAYOUTS:
        raise ValueError(f"unknown layout {name!r}; choose one of {', '.join(LAYOUTS)}")
    counts = np.asarray(counts, dtype=np.int64)
    num_strands = counts.shape[0]
    point_start = np.zeros(num_strands + 1, dtype=np.int64)
    np.cumsum(counts, out=point_start[1:])
    num_points = int(point_start[-1])
    local = np.arange(num_points, dtype=np.int64) - np.repeat(point_start[:-1], counts)

    if name == "strand-major":
        order = np.arange(num_strands, dtype=np.int64)
    else:
        order = np.argsort(counts, kind="stable").astype(np.int64)
    sorted_counts = counts[order]
    # groups of equal count, in device order
    edges = np.flatnonzero(np.diff(sorted_counts)) + 1
    starts = np.concatenate([[0], edges]).astype(np.int64)
    sizes = np.diff(np.concatenate([starts, [num_strands]])).astype(np.int64)
    groups = tuple((int(sorted_counts[a]), int(a), int(b)) for a, b in zip(starts, sizes) if b > 0)

    base = np.empty(num_strands, dtype=np.int64)
    stride = np.empty(num_strands, dtype=np.int64)
    if name == "strand-major":
        base[:] = point_start[:-1]
        stride[:] = 1
    else:
        offset = 0
        for count, first, size in groups:
            base[first : first + size] = offset + np.arange(size)
            stride[first : first + size] = size
            offset += count * size
    # device strand of every input strand
    device_strand = np.empty(num_strands, dtype=np.int64)
    device_strand[order] = np.arange(num_strands)
    strand_of_point = np.repeat(device_strand, counts)
    slot_of_point = base[strand_of_point] + local * stride[strand_of_point]
    return Layout(
        name=name,
        strand_order=order,
        strand_base=base,
        strand_stride=stride,
        strand_count=sorted_counts,
        slot_of_point=slot_of_point,
        groups=groups,
    )
