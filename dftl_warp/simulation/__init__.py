"""dftl_warp.simulation."""
