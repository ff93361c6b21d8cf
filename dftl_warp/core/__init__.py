"""dftl_warp.core."""
