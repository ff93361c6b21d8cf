"""dftl_warp.kernels.features."""
