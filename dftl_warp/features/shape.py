"""Shape retention (:class:`ShapeRetention`): each strand keeps its rest shape in its own frame.

Model data: the stiffness per device strand (in [0, 1], per substep), each strand's first rest
frame (a quaternion) and each particle's rest direction in the frame of the segment before it
(:func:`rest_frames`, parallel transport along the rest shape). USD: ``dftl:shapeStiffness``
(scene or curves prim). The sweep (``kernels/features/shape.py``) moves each prediction
``stiffness`` of the way toward ``leader + rest_length x frame(rest direction)``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import warp as wp

from ..core.layout import strand_offsets
from .base import authored_per_strand, per_strand, quat_between, quat_multiply, quat_rotate

#: name -> (type, where: "scene", "curves" or "both", description)
ATTRIBUTES = {
    "dftl:shapeStiffness": (float, "both", "shape retention in [0, 1] per substep; 0 or unset: off"),
}


@dataclass(frozen=True, eq=False)
class ShapeRetention:
    """Keep each strand's rest shape (curls, styling) in its own local frame.

    ``stiffness`` in [0, 1], a number or one per input strand (0 turns it off for that curve):
    the share of the way each prediction moves toward its rest-shape target per substep."""

    stiffness: object = 0.5

    def __post_init__(self):
        s = np.asarray(self.stiffness, dtype=np.float64)
        if not np.isfinite(s).all() or np.any(s < 0) or np.any(s > 1):
            raise ValueError("shape retention stiffness must be in [0, 1]")
        object.__setattr__(self, "stiffness", s)

    flags = frozenset({"shape"})


def rest_frames(points, counts):
    """Rest frame of each strand's first segment (S, 4) and each particle's rest direction in
    the frame of the segment before it (N, 3), by parallel transport along the rest shape."""
    points = np.asarray(points, dtype=np.float64)
    counts = np.asarray(counts, dtype=np.int64)
    starts = strand_offsets(counts)
    ex = np.array([1.0, 0.0, 0.0])
    rest_dir = np.tile(ex, (len(points), 1))
    frame = np.tile([0.0, 0.0, 0.0, 1.0], (len(counts), 1))
    direction = np.tile(ex, (len(counts), 1))
    first = np.zeros((len(counts), 4))
    first[:, 3] = 1.0
    for i in range(1, int(counts.max(initial=0))):
        s = np.flatnonzero(counts > i)
        seg = points[starts[s] + i] - points[starts[s] + i - 1]
        length = np.linalg.norm(seg, axis=1)
        ok = length > 0
        t = np.where(ok[:, None], seg / np.where(ok, length, 1.0)[:, None], direction[s])
        if i == 1:
            q = quat_between(np.broadcast_to(ex, t.shape), t)
            first[s] = q
            frame[s] = q
        else:
            conj = frame[s] * np.array([-1.0, -1.0, -1.0, 1.0])
            rest_dir[starts[s] + i] = quat_rotate(conj, t)
            q = quat_multiply(quat_between(direction[s], t), frame[s])
            frame[s] = np.where(ok[:, None], q / np.linalg.norm(q, axis=1, keepdims=True), frame[s])
        direction[s] = t
    return first, rest_dir


def build(shape: ShapeRetention, ctx) -> dict:
    """Device arrays ``shape_stiffness`` (per device strand), ``shape_rest_frame`` (per device
    strand) and ``shape_rest_dir`` (per slot) of a model being built (``ctx``: the model's fields)."""
    lay, ftype, scalar, vec3, device = ctx["layout"], ctx["ftype"], ctx["scalar"], ctx["vec3"], ctx["device"]
    order = lay.strand_order
    stiffness = per_strand(shape.stiffness, len(ctx["counts"]), "shape retention stiffness")
    first, rest_dir = rest_frames(ctx["points"], ctx["counts"])
    dirs = np.zeros((lay.num_slots, 3), dtype=ftype)
    dirs[lay.slot_of_point] = rest_dir

    def arr(a, dtype):
        return wp.array(np.ascontiguousarray(a), dtype=dtype, device=device)

    return {"shape_stiffness": arr(stiffness[order].astype(ftype), scalar),
            "shape_rest_frame": arr(first[order].astype(ftype), wp.types.quaternion(dtype=scalar)),
            "shape_rest_dir": arr(dirs, vec3)}


def fill_struct(st, arrays: dict) -> None:
    st.shape_stiffness = arrays["shape_stiffness"]
    st.shape_rest_frame = arrays["shape_rest_frame"]
    st.shape_rest_dir = arrays["shape_rest_dir"]


def from_attributes(scene: dict, curves: list, counts: list, where: str) -> list:
    """ShapeRetention from authored ``dftl:shapeStiffness`` values (any > 0)."""

    def unit(v, msg):
        if not 0 <= v <= 1:
            raise ValueError(f"{msg}: must be in [0, 1]")

    stiffness = authored_per_strand(scene, curves, counts, "dftl:shapeStiffness", where, unit)
    return [ShapeRetention(stiffness)] if np.any(stiffness > 0) else []
