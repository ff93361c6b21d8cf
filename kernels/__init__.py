"""Warp kernels of dftl-warp, grouped by concern. Installed as ``dftl_warp.kernels``.

- :mod:`.layout`: the one indexing helper that hides the particle layout;
- :mod:`.ftl`: the follow-the-leader step (posterior and prior velocity correction);
- :mod:`.diagnostics`: energy, stretch and speed reductions;
- :mod:`.render`: the hair preview ray tracer (camera rays, strand BVH, gprims, hair shading).
"""
