"""dftl_warp.study."""
