"""Warp kernels of dftl-warp, grouped by concern. Installed as ``dftl_warp.kernels``.

- :mod:`.layout`: the one indexing helper that hides the particle layout;
- :mod:`.ftl`: the follow-the-leader step (posterior and prior velocity correction);
- :mod:`.fused`: a frame's substeps in one launch, each strand's state on chip;
- :mod:`.pipelined`: a frame's substeps in one launch for strands of any length, one lane per substep;
- :mod:`.diagnostics`, :mod:`.energy`: energy, stretch and speed reductions;
- :mod:`.featured`: the step specialized to a scene's features (``wp.static`` flags), using
  :mod:`.collide` (colliders), :mod:`.grid` (hair-hair);
- :mod:`.binding`: roots bound to a deforming mesh;
- :mod:`.reference`, :mod:`.pbd`: the RATTLE reference integrator and position-based dynamics;
- :mod:`.output`: device state to per-prim local-space samples;
- :mod:`.render`: the hair preview ray tracer (camera rays, strand BVH, gprims, hair shading);
- :mod:`.synthetic`: grooms built on the device for benchmarks.
"""
