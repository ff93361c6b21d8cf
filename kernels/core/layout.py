"""The indexing helper: the only place a kernel learns where a particle lives."""

import warp as wp


@wp.func
def particle(strand_base: wp.int32, strand_stride: wp.int32, i: wp.int32):
    """Slot of particle ``i`` of a strand whose first particle is at ``strand_base``."""
    return strand_base + i * strand_stride
