"""dftl_warp.kernels.output."""
