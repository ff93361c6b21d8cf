"""Sub-commands of ``dftl-warp``; see :mod:`dftl_warp.cli`."""
