"""Large synthetic grooms built directly on the device (benchmarks, memory limits).

:func:`uniform_groom` makes ``num_strands`` straight strands of ``count`` vertices without any
per-particle host array, so grooms of billions of particles can be allocated and stepped.
Host conversions (``points_from_device``) are not available on such a model.
"""

from __future__ import annotations

import numpy as np
import warp as wp

from .kernels.synthetic import straight_strands_kernel
from .layout import Layout, default_layout
from .model import Model
from .precision import scalar_type, vec3_type
from .state import State


def uniform_groom(num_strands: int, count: int, *, device="cpu", precision="float32", layout=None,
                  spacing: float = 0.005, with_corrections: bool = True):
    """(Model, State) of ``num_strands`` straight strands of ``count`` vertices, ``spacing`` m apart."""
    device = wp.get_device(device)
    name = layout or default_layout(str(device))
    S = int(num_strands)
    strands = np.arange(S, dtype=np.int64)
    if name == "strand-major":
        base, stride = strands * count, np.ones(S, dtype=np.int64)
    else:
        base, stride = strands, np.full(S, S, dtype=np.int64)
    lay = Layout(name=name, strand_order=strands, strand_base=base, strand_stride=stride,
                 strand_count=np.full(S, count, dtype=np.int64), slot_of_point=None,
                 groups=((int(count), 0, S),))
    scalar, vec3 = scalar_type(precision), vec3_type(precision)
    i32 = lambda a: wp.array(a.astype(np.int32), dtype=wp.int32, device=device)  # noqa: E731
    n = S * int(count)
    rest = wp.empty(n, dtype=scalar, device=device)
    positions = wp.empty(n, dtype=vec3, device=device)
    roots = wp.empty(S, dtype=vec3, device=device)
    model = Model(device=device, precision=precision, layout=lay, counts=lay.strand_count, origin=np.zeros(3),
                  strand_base=i32(base), strand_stride=i32(stride), strand_count=i32(lay.strand_count),
                  rest_lengths=rest, rest_positions=None, root_rest=roots)
    wp.launch(straight_strands_kernel(scalar), dim=S, device=device,
              inputs=[model.strand_base, model.strand_stride, model.strand_count, spacing],
              outputs=[positions, rest, roots])
    state = State(positions=positions, velocities=wp.zeros(n, dtype=vec3, device=device),
                  corrections=wp.zeros(n, dtype=vec3, device=device) if with_corrections else None)
    return model, state
