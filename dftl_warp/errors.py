"""Errors meant for the user: one line, no traceback."""


class UserError(Exception):
    """Bad input or settings. The message names the file, prim and index where it can."""
