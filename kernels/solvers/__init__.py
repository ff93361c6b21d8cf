"""dftl_warp.kernels.solvers."""
