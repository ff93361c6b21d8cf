"""Warp kernels of dftl-warp, grouped by concern. Installed as ``dftl_warp.kernels``.

- :mod:`.layout`: the one indexing helper that hides the particle layout;
- :mod:`.ftl`: the follow-the-leader step (posterior and prior velocity correction);
- :mod:`.diagnostics`: energy, stretch and speed reductions;
- :mod:`.featured`: the step specialized to a scene's features (``wp.static`` flags), using
  :mod:`.collide` (colliders), :mod:`.grid` (hair-hair), :mod:`.shape` (shape retention);
- :mod:`.binding`: roots bound to a deforming mesh.
"""
