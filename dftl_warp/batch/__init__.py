"""dftl_warp.batch."""
