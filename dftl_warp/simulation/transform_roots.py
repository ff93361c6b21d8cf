"""Root paths of prims moved by their transforms, computed on the device (``kernels/simulation/transform_roots.py``).

The roots of a prim are fixed in its local space, so over a frame they follow its local-to-world
matrix: the frame's host work is a few 4x4 matrices per prim (the matrices at the frame's start and
end, and their rates: :func:`~dftl_warp.core.state.frame_velocity` of the matrices, the same
difference the host path applies to the frames' world roots, :func:`root_paths.frame_path
<dftl_warp.simulation.root_paths.frame_path>`), and a kernel per part writes every strand's targets
and the C1 path's deviations into the Control (and the elastic solver's clamp ghosts and their
rotations). The host path built, checked and copied (S, 3) arrays four times a frame, and the clamps'
(S, 3, 3) rotations: at 100k elastic strands 0.1 s a frame of host work against about 12 ms of
solver on an H200 (``scripts/bench_multi_gpu.py --sections elastic``, 2026-11-28).

Not used with ``--tolerance``, whose sample runs take the host arrays.
"""

from __future__ import annotations

import numpy as np

from ..core.state import frame_velocity
from .root_paths import shot


class TransformRoots:
    """Device root paths of group ``group`` of ``sim`` (roots: ``sim._roots_local``; clamp ghosts:
    ``group.clamps``, the elastic solver's)."""

    def __init__(self, sim, group):
        import warp as wp

        self.group = group
        self.clamps = group.clamps
        members = group.members
        counts = [sim.scene.curves[i].num_strands for i in members]
        prim = np.repeat(np.arange(len(members), dtype=np.int32), counts)
        roots = np.concatenate([sim._roots_local[i] for i in members]).astype(np.float64)
        ghosts = None if group.clamps is None else np.concatenate(group.clamps.local).astype(np.float64)
        ranges = getattr(group.model, "strand_ranges", [(0, group.num_strands)])
        self.parts = []
        for model, (s0, s1) in zip(getattr(group.model, "parts", [group.model]), ranges):
            order = s0 + model.layout.strand_order
            dev = model.device
            part = {"model": model, "prim": wp.array(prim[order], dtype=wp.int32, device=dev),
                    "roots": wp.array(roots[order], dtype=wp.vec3d, device=dev),
                    "origin": wp.vec3d(*np.asarray(model.origin, dtype=np.float64))}
            if ghosts is not None:
                part["ghosts"] = wp.array(ghosts[order], dtype=wp.vec3d, device=dev)
            self.parts.append(part)

    def frame(self, sim, frame: int, nxt: int) -> None:
        """Root targets (and clamps) of the frame ``frame -> nxt`` on every part's device."""
        import warp as wp

        from ..kernels.simulation.transform_roots import gather_rotations_kernel, transform_roots_kernel

        g = self.group
        duration = (nxt - frame) / sim.scene.stage.time_codes_per_second
        first, last = shot(sim)

        def matrices(f):
            return np.stack([sim._matrix(i, f) for i in g.members])

        frames = (matrices(frame), matrices(nxt), frame_velocity(matrices, frame, first, last, duration),
                  frame_velocity(matrices, nxt, first, last, duration))
        rotations = None
        if self.clamps is not None:
            rotations = [self.clamps.prim_rotations(sim._matrix, g.members, f) for f in (frame, nxt)]
        controls = getattr(g.control, "parts", [g.control])
        solvers = getattr(g.solver, "parts", [g.solver])
        for part, control, solver in zip(self.parts, controls, solvers):
            model, dev = part["model"], part["model"].device
            if model.num_strands == 0:
                continue
            per_prim = [wp.array(m, dtype=wp.mat44d, device=dev) for m in frames]
            kernel = transform_roots_kernel(model.scalar)
            targets = control.root_target_arrays(duration)
            wp.launch(kernel, dim=model.num_strands, device=dev,
                      inputs=[part["prim"], part["roots"], part["origin"], *per_prim, float(duration)],
                      outputs=[targets["start"], targets["end"], targets["deviation_start"], targets["deviation_end"]])
            if rotations is None:
                continue
            clamps = solver.clamp_target_arrays()
            wp.launch(kernel, dim=model.num_strands, device=dev,
                      inputs=[part["prim"], part["ghosts"], part["origin"], *per_prim, float(duration)],
                      outputs=[clamps["start"], clamps["end"], clamps["deviation_start"], clamps["deviation_end"]])
            wp.launch(gather_rotations_kernel(model.scalar), dim=model.num_strands, device=dev,
                      inputs=[part["prim"], *(wp.array(r, dtype=wp.mat33d, device=dev) for r in rotations)],
                      outputs=[clamps["rotation_start"], clamps["rotation_end"]])


def drive(sim, k: int, group, frame: int, nxt: int) -> bool:
    """Set group ``k``'s root (and clamp) targets for the frame on the device, where its prims' roots
    move with their transforms alone (no ``--tolerance``); False where the caller's host path must."""
    if sim.tolerance is not None:
        return False
    driver = sim.transform_roots.get(k)
    if driver is None or driver.group is not group or driver.clamps is not group.clamps:
        driver = sim.transform_roots[k] = TransformRoots(sim, group)   # again once the clean start moved the clamps
    driver.frame(sim, frame, nxt)
    return True
