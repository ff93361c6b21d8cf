"""dftl_warp.output."""
