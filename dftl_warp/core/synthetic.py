"""Large synthetic grooms built directly on the device (benchmarks, memory limits).

:func:`uniform_groom` makes ``num_strands`` straight strands of ``count`` vertices without any
per-particle host array, so grooms of billions of particles can be allocated and stepped.
Host conversions (``points_from_device``) are not available on such a model.
"""

from __future__ import annotations

import numpy as np
import warp as wp

from ..kernels.core.synthetic import straight_strands_kernel
from .layout import MAX_SLOTS, Layout, default_interleave, default_layout, group_slots
from .model import Model
from .precision import scalar_type, vec3_type
from .state import State


def uniform_groom(num_strands: int, count: int, *, device="cpu", precision="float32", layout=None,
                  spacing: float = 0.005, with_corrections: bool = True, interleave: int | None = None):
    """(Model, State) of ``num_strands`` straight strands of ``count`` vertices, ``spacing`` m apart.

    ``interleave``: state vectors per 32-strand chunk of a particle-major layout (default
    :func:`~dftl_warp.core.layout.default_interleave`)."""
    device = wp.get_device(device)
    name = layout or default_layout(str(device))
    if interleave is None:
        lay = _uniform_layout(name, int(num_strands), int(count),
                              default_interleave(name, str(device), corrections=with_corrections))
        if lay.storage_length > MAX_SLOTS:  # past Warp's 32-bit array shapes: the plain layout holds more
            lay = _uniform_layout(name, int(num_strands), int(count), 1)
    else:
        lay = _uniform_layout(name, int(num_strands), int(count), int(interleave))
        if lay.storage_length > MAX_SLOTS:
            raise ValueError(f"{num_strands} strands x {count} interleaving {interleave} state vectors pass 2^31 "
                             "slots; use interleave=1")
    S, interleave = int(num_strands), lay.interleave
    base, stride = lay.strand_base, lay.strand_stride
    scalar, vec3 = scalar_type(precision), vec3_type(precision)
    i32 = lambda a: wp.array(a.astype(np.int32), dtype=wp.int32, device=device)  # noqa: E731
    n = lay.num_slots
    rest = wp.zeros(n, dtype=scalar, device=device) if interleave > 1 else wp.empty(n, dtype=scalar, device=device)
    if interleave > 1:
        state = State.interleaved(wp.zeros(lay.storage_length, dtype=vec3, device=device), lay, with_corrections)
        positions = state.positions
    else:
        positions = wp.empty(n, dtype=vec3, device=device)
    roots = wp.empty(S, dtype=vec3, device=device)
    model = Model(device=device, precision=precision, layout=lay, counts=lay.strand_count, origin=np.zeros(3),
                  strand_base=i32(base), strand_stride=i32(stride), strand_count=i32(lay.strand_count),
                  rest_lengths=rest, rest_positions=None, root_rest=roots)
    wp.launch(straight_strands_kernel(scalar), dim=S, device=device,
              inputs=[model.strand_base, model.strand_stride, model.strand_count, spacing],
              outputs=[positions, rest, roots])
    if interleave == 1:
        state = State(positions=positions, velocities=wp.zeros(n, dtype=vec3, device=device),
                      corrections=wp.zeros(n, dtype=vec3, device=device) if with_corrections else None)
    return model, state


def _uniform_layout(name: str, S: int, count: int, interleave: int) -> Layout:
    """The layout ``name`` of ``S`` strands of ``count`` vertices, built without per-point arrays."""
    strands = np.arange(S, dtype=np.int64)
    slot_space = None
    if name == "strand-major":
        base, stride = strands * count, np.ones(S, dtype=np.int64)
    else:
        base, row = group_slots(S, interleave)
        stride = np.full(S, row, dtype=np.int64)
        slot_space = count * row if interleave > 1 else None
    return Layout(name=name, strand_order=strands, strand_base=base, strand_stride=stride,
                  strand_count=np.full(S, count, dtype=np.int64), slot_of_point=None,
                  groups=((count, 0, S),), interleave=interleave, slot_space=slot_space)
