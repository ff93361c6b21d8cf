"""dftl_warp.kernels.core."""
