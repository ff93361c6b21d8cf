"""dftl_warp.usd."""
