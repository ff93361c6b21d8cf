"""Errors meant for the user: one line, no traceback; and :func:`plural`, for counts in messages."""


class UserError(Exception):
    """Bad input or settings. The message names the file, prim and index where it can."""


def plural(n: int, noun: str, nouns: str | None = None) -> str:
    """``n`` and the noun that fits it: ``plural(1, "strand")`` is "1 strand", ``plural(3,
    "strand")`` "3 strands", ``plural(2, "vertex", "vertices")`` "2 vertices"."""
    return f"{n} {noun if n == 1 else (nouns or noun + 's')}"
