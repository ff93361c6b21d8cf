"""The package version (kept at 0.1.0 through the layout redesign: batch settings hashes include it)."""

__version__ = "0.1.0"
