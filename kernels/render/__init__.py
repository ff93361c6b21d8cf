"""dftl_warp.kernels.render."""
