"""Particle layout: where particle ``i`` of strand ``s`` lives in the device arrays.

Every per-particle device array (positions, velocities, corrections, rest lengths) uses the same
layout, described per *device strand* by two integers::

    slot(s, i) = strand_base[s] + i * strand_stride[s]

which the kernels evaluate through one helper, :func:`dftl_warp.kernels.core.layout.particle`.

Two layouts exist:

``"strand-major"``
    each strand's particles are contiguous (stride 1). Best for the serial CPU backend, where one
    thread walks a strand through consecutive memory.
``"particle-major"``
    strands are grouped by vertex count; inside a group of ``S`` strands, particle ``i`` of every
    strand is contiguous (stride ``S``), so neighbouring GPU threads touch neighbouring memory.
    Best on CUDA (measured in ``scripts/bench.py``; see ``docs/benchmarks.md``).

A particle-major layout may *interleave* ``F`` state vectors (``interleave=F``: positions,
velocities and carried corrections, ``F = 3``): the strands of a group are padded to a multiple
of 32 and every particle row is cut into chunks of 32 strands; a chunk holds ``32 F`` slots, the
32 positions first, then the 32 velocities, then the 32 corrections. A particle's slot is its
position's; its field ``f`` lives ``32 f`` slots further (:class:`~dftl_warp.core.state.State` keeps
the fields in one buffer and hands out views offset by 32 and 64 slots). Still affine per strand,
``slot(s, i) = strand_base[s] + i * strand_stride[s]`` with ``strand_stride = F * padded strands``,
so every kernel is unchanged; a warp's state for one particle row is one contiguous 32 x 36 B
block instead of three blocks in three arrays, which the H200 streams faster (docs/benchmarks.md).
Slots past the chunk's 32 positions are holes in every other per-particle array (rest lengths):
``num_slots`` is ``F x`` the padded point count, not the point count.

Device strands are ordered so that strands of one group are consecutive; given the roots, a
particle-major group orders its strands along a Morton (Z-order) curve of their roots, so the 32
strands of a warp are neighbours in space and their particles read the same cells of the hair-hair
grid and of a collider's distance field (:func:`morton_order`). The host keeps the mapping back to
the caller's order (:attr:`Layout.slot_of_point`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .bounds import box

LAYOUTS = ("strand-major", "particle-major")

#: strands per interleaved chunk (one warp)
CHUNK_STRANDS = 32


def zero_length_segment(points, counts):
    """(strand, segment) of the first segment of zero length (two consecutive points of one strand
    coincide) among strands ``points`` (N, 3) with vertex ``counts``, both 0-based (segment ``i``
    joins the strand's points ``i`` and ``i + 1``), or None."""
    counts = np.asarray(counts, np.int64).reshape(-1)
    points = np.asarray(points, np.float64).reshape(-1, 3)
    if points.shape[0] < 2:
        return None
    owner = np.repeat(np.arange(counts.size), counts)
    zero = np.all(points[1:] == points[:-1], axis=1) & (owner[1:] == owner[:-1])
    if not zero.any():
        return None
    j = int(np.flatnonzero(zero)[0])
    strand = int(owner[j])
    return strand, j - int(strand_offsets(counts)[strand])


def incoming_lengths(points, counts) -> np.ndarray:
    """Per point of strands ``points`` (N, 3) with vertex ``counts``: the length of the segment
    ending at it (its rest length when ``points`` are the rest shape), 0 at each strand's root."""
    points = np.asarray(points, np.float64).reshape(-1, 3)
    lengths = np.zeros(points.shape[0])
    lengths[1:] = np.linalg.norm(np.diff(points, axis=0), axis=1)
    lengths[strand_offsets(counts)[np.asarray(counts).reshape(-1) > 0]] = 0.0   # roots have no incoming segment
    return lengths


def strand_offsets(counts, *, with_end: bool = False) -> np.ndarray:
    """Index of each strand's first point in the concatenated points of strands with vertex
    ``counts`` (int64, one per strand); ``with_end``: one more entry, the total point count (so
    strand ``s`` is ``offsets[s]:offsets[s + 1]``)."""
    counts = np.asarray(counts, dtype=np.int64).reshape(-1)
    offsets = np.zeros(counts.shape[0] + 1, dtype=np.int64)
    np.cumsum(counts, out=offsets[1:])
    return offsets if with_end else offsets[:-1]


def default_layout(device: str) -> str:
    """The layout measured fastest on ``device`` (``"cpu"`` or ``"cuda:N"``)."""
    return "particle-major" if str(device).startswith("cuda") else "strand-major"


#: most elements of one Warp array (its shapes are 32-bit)
MAX_SLOTS = 2**31 - 1


def default_interleave(layout: str, device: str, features: bool = False, corrections: bool = True) -> int:
    """State vectors to interleave for a particle-major model on CUDA without features: 3
    (positions, velocities, corrections), or 2 when the solver carries no corrections; else 1.
    Feature kernels that walk every slot (the hair volume grid) need a slot space without holes.
    Builders fall back to 1 where the interleaved slot space would pass :data:`MAX_SLOTS`."""
    if layout != "particle-major" or not str(device).startswith("cuda") or features:
        return 1
    return 3 if corrections else 2


def read_only(array):
    """A read-only view of the numpy ``array`` (no copy; the array itself stays as it was), or
    ``array`` itself when it is not a numpy array (None). The host arrays of a Model and its Layout
    are these: an edit in place (``model.origin[0] = nan``) was taken without a word."""
    if not isinstance(array, np.ndarray):
        return array
    view = array.view()
    view.flags.writeable = False
    return view


@dataclass(frozen=True)
class Layout:
    """Host-side description of a particle layout (all arrays are numpy int64, read-only)."""

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
    #: state vectors interleaved per 32-strand chunk (1: none; particle-major only)
    interleave: int = 1
    #: length of every per-particle device array (None: one slot per point)
    slot_space: int | None = None

    def __post_init__(self):
        for name in ("strand_order", "strand_base", "strand_stride", "strand_count", "slot_of_point"):
            object.__setattr__(self, name, read_only(getattr(self, name)))

    @property
    def num_points(self) -> int:
        return int(self.strand_count.sum())

    @property
    def num_slots(self) -> int:
        """Length of every per-particle device array (the point count unless interleaved)."""
        return self.num_points if self.slot_space is None else int(self.slot_space)

    @property
    def chunk_slots(self) -> int:
        """Slot distance between neighbouring 32-strand chunks of one particle row."""
        return CHUNK_STRANDS * self.interleave

    @property
    def storage_length(self) -> int:
        """Entries of a State's buffer: the slot space plus the last field's offset, so that every
        field's view has ``num_slots`` entries (the slot space itself when not interleaved)."""
        return self.num_slots + CHUNK_STRANDS * (self.interleave - 1)


def group_slots(size: int, interleave: int) -> tuple[np.ndarray, int]:
    """First slots (relative to the group) of a particle-major group of ``size`` strands, and the
    group's row stride (slots between a strand's consecutive particles); ``interleave`` > 1
    interleaves that many state vectors per 32-strand chunk."""
    a = np.arange(size, dtype=np.int64)
    if interleave == 1:
        return a, size
    padded = -(-size // CHUNK_STRANDS) * CHUNK_STRANDS
    return (a // CHUNK_STRANDS) * (CHUNK_STRANDS * interleave) + a % CHUNK_STRANDS, interleave * padded


def morton_order(points: np.ndarray, bits: int = 10) -> np.ndarray:
    """Morton (Z-order) codes (uint64) of ``points`` (N, 3) quantised to ``bits`` bits per axis over
    their bounding box: points close in space get close codes."""
    p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    if p.shape[0] == 0:
        return np.zeros(0, dtype=np.uint64)
    lo, hi = box(p)
    scale = np.where(hi > lo, ((1 << bits) - 1) / np.where(hi > lo, hi - lo, 1.0), 0.0)
    q = np.clip(np.floor((p - lo) * scale), 0, (1 << bits) - 1).astype(np.uint64)
    code = np.zeros(p.shape[0], dtype=np.uint64)
    for b in range(bits):
        for axis in range(3):
            code |= ((q[:, axis] >> np.uint64(b)) & np.uint64(1)) << np.uint64(3 * b + axis)
    return code


def make_layout(counts: np.ndarray, name: str, interleave: int = 1, roots: np.ndarray | None = None) -> Layout:
    """Build the layout ``name`` for strands with vertex ``counts`` (input order), interleaving
    ``interleave`` state vectors per 32-strand chunk (particle-major only); with ``roots`` (S, 3), a
    particle-major layout orders each group's strands along the Morton curve of their roots."""
    if name not in LAYOUTS:
        raise ValueError(f"unknown layout {name!r}; choose one of {', '.join(LAYOUTS)}")
    interleave = int(interleave)
    if interleave < 1 or (interleave > 1 and name != "particle-major"):
        raise ValueError(f"layout {name!r} cannot interleave {interleave} state vectors")
    counts = np.asarray(counts, dtype=np.int64)
    num_strands = counts.shape[0]
    point_start = strand_offsets(counts, with_end=True)
    num_points = int(point_start[-1])
    local = np.arange(num_points, dtype=np.int64) - np.repeat(point_start[:-1], counts)

    if name == "strand-major":
        order = np.arange(num_strands, dtype=np.int64)
    elif roots is not None and num_strands:
        order = np.lexsort((morton_order(roots), counts)).astype(np.int64)
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
            rel, row = group_slots(size, interleave)
            base[first : first + size] = offset + rel
            stride[first : first + size] = row
            offset += count * row
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
        interleave=interleave,
        slot_space=(offset if interleave > 1 else None) if name == "particle-major" else None,
    )
