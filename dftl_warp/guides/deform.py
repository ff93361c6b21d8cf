"""Guide-driven render strands on the device (float32, CPU or CUDA).

>>> deformer = GuideDeformer(binding, device="cuda:0")
>>> render = deformer.deform(guide_points)          # wp.array of vec3, render points in input order
>>> render = deformer.deform(state.positions, base=model.strand_base, stride=model.strand_stride)

Two launches per frame: :data:`~dftl_warp.kernels.guides.deform.guide_frames` (one thread per
guide) and the deformation (one thread per render strand).
"""

from __future__ import annotations

import numpy as np
import warp as wp

from ..kernels.guides.deform import deform_kernel, guide_frames
from .binding import Binding


class GuideDeformer:
    """A :class:`~dftl_warp.guides.binding.Binding` on a device, ready to deform frames."""

    def __init__(self, binding: Binding, device="cpu"):
        b = binding
        self.binding = b
        self.device = wp.get_device(device)
        d = self.device
        i32 = lambda a: wp.array(np.asarray(a, dtype=np.int32), dtype=wp.int32, device=d)  # noqa: E731
        f32 = lambda a: wp.array(np.asarray(a, dtype=np.float32), dtype=wp.float32, device=d)  # noqa: E731
        G, Mg = b.num_guides, int(b.guide_frac.shape[0])
        self.num_guides, self.num_guide_points = G, Mg
        self.num_render, self.num_render_points = b.num_render, int(b.t.shape[0])
        # guide side (per guide / guide vertex)
        self.guide_start = i32(b.guide_starts)
        self.guide_count = i32(b.guide_counts)
        self.guide_frac = f32(b.guide_frac)
        self.ref_guide = i32(b.ref_guide)
        self.ref_vertex = i32(b.ref_vertex)
        self.flat_stride = i32(np.ones(G))
        self.P = wp.empty(Mg, dtype=wp.vec3, device=d)
        self.T = wp.empty(Mg, dtype=wp.vec3, device=d)
        self.N = wp.empty(Mg, dtype=wp.vec3, device=d)
        # render side (the binding proper)
        self.render_start = i32(b.render_starts)
        self.render_count = i32(b.render_counts)
        self.ids = wp.array(b.guide_ids.astype(np.int32), dtype=wp.vec4i, device=d)
        self.weights = wp.array(b.weights.astype(np.float32), dtype=wp.vec4, device=d)
        self.t = f32(b.t)
        self.offsets = wp.array(b.offsets.reshape(-1, 3).astype(np.float32), dtype=wp.vec3, device=d)
        self.kernel = deform_kernel(b.frames == "per-guide", b.clump > 0)

    # ---- memory
    def binding_nbytes(self) -> int:
        """Device bytes of the render-side binding (what grows with the render strands)."""
        return sum(a.capacity for a in (self.render_start, self.render_count, self.ids, self.weights,
                                        self.t, self.offsets))

    def guide_nbytes(self) -> int:
        """Device bytes of the guide-side arrays (rest fractions, references, frames)."""
        return sum(a.capacity for a in (self.guide_start, self.guide_count, self.guide_frac, self.ref_guide,
                                        self.ref_vertex, self.flat_stride, self.P, self.T, self.N))

    def bytes_per_render_strand(self) -> float:
        return self.binding_nbytes() / max(self.num_render, 1)

    # ---- per frame
    def deform(self, guide_points, *, base=None, stride=None, out=None) -> wp.array:
        """Render points (wp.array of vec3 on the device, input order) from the guides' current points.

        ``guide_points``: (M, 3) numpy or a wp.array of vec3 on the device. By default it is flat in
        the binding's guide order (``base`` = guide starts, ``stride`` = 1); with ``base`` and
        ``stride`` (int32 device arrays, one per guide) vertex ``i`` of guide ``g`` is
        ``guide_points[base[g] + i * stride[g]]`` (a simulation's particle layout). Render points come
        out in the coordinates the guide points are in (a rigid offset such as a model origin passes
        through)."""
        d = self.device
        if not isinstance(guide_points, wp.array):
            pts = np.asarray(guide_points, dtype=np.float32)
            if pts.ndim != 2 or pts.shape[1] != 3:
                raise ValueError(f"guide_points must have shape (M, 3), got {pts.shape}")
            if base is None and pts.shape[0] != self.num_guide_points:
                raise ValueError(f"guide_points holds {pts.shape[0]} points, the binding's guides {self.num_guide_points}")
            guide_points = wp.array(pts, dtype=wp.vec3, device=d)
        elif base is None and guide_points.shape[0] != self.num_guide_points:
            raise ValueError(f"guide_points holds {guide_points.shape[0]} points, the binding's guides "
                             f"{self.num_guide_points}")
        if (base is None) != (stride is None):
            raise ValueError("base and stride go together")
        if base is None:
            base, stride = self.guide_start, self.flat_stride
        if out is None:
            out = wp.empty(self.num_render_points, dtype=wp.vec3, device=d)
        wp.launch(guide_frames, dim=self.num_guides, device=d,
                  inputs=[guide_points, base, stride, self.guide_start, self.guide_count, self.ref_guide,
                          self.ref_vertex], outputs=[self.P, self.T, self.N])
        b = self.binding
        wp.launch(self.kernel, dim=self.num_render, device=d,
                  inputs=[self.P, self.T, self.N, self.guide_start, self.guide_count, self.guide_frac,
                          self.render_start, self.render_count, self.ids, self.weights, self.t, self.offsets,
                          b.k, b.clump, b.clump_shape], outputs=[out])
        return out

    def deform_numpy(self, guide_points) -> np.ndarray:
        """:meth:`deform` with host arrays in and out ((Vr, 3) float64)."""
        return self.deform(guide_points).numpy().astype(np.float64)
