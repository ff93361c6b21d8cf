"""dftl_warp.kernels.simulation."""
