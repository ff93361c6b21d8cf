"""Errors meant for the user: one line, no traceback; :func:`plural`, for counts in messages; and
:class:`WarningRoute`, which makes Python's warnings one-line messages of the program."""

from __future__ import annotations

import sys
import warnings


class UserError(Exception):
    """Bad input or settings. The message names the file, prim and index where it can."""


def check_path(name: str, value) -> None:
    """TypeError naming ``name`` unless ``value`` is a file path (a str or os.PathLike): None gave
    os.fspath's "expected str, bytes or os.PathLike object", which named no argument."""
    import os

    if not isinstance(value, (str, os.PathLike)):
        raise TypeError(f"{name} must be a file path (str or os.PathLike), got "
                        f"{'None' if value is None else type(value).__name__}")


def plural(n: int, noun: str, nouns: str | None = None) -> str:
    """``n`` and the noun that fits it: ``plural(1, "strand")`` is "1 strand", ``plural(3,
    "strand")`` "3 strands", ``plural(2, "vertex", "vertices")`` "2 vertices"."""
    return f"{n} {noun if n == 1 else (nouns or noun + 's')}"


#: categories meant for developers, not users: shown as Python shows them (by default, not at all)
DEVELOPER_WARNINGS = (DeprecationWarning, PendingDeprecationWarning, ImportWarning, ResourceWarning)


class WarningRoute:
    """A context in which Python warnings -- ours (a collider approximated), numpy's (a
    RuntimeWarning such as "overflow encountered in cast"), Warp's (its logger's) -- become
    one-line messages ``say(text)`` instead of Python's two lines ``file.py:123: UserWarning: ...``
    on stderr. ``text`` is ``WHERE: message`` (``where``: the file being worked on; left out when
    the message starts with it or is of one of the ``named`` categories, whose messages name their
    file), blanks folded, the category added where it is not a UserWarning. ``say`` and ``where``
    may change inside (a command passes its warnings to the run once it starts); while it is None
    they are held (:attr:`held`, :meth:`keep_in`). UserWarnings and RuntimeWarnings are all shown,
    whatever the filters say, and ``say`` is called for each one: a repeated one is the caller's to
    keep once (:func:`once`, :meth:`keep_in`); :data:`DEVELOPER_WARNINGS` go their usual way.
    Entered, it also routes Warp's logger's warnings (if Warp is imported) through Python's."""

    def __init__(self, say=None, where: str = "", named: tuple = ()):
        self.say, self.where, self.named = say, where, tuple(named)
        #: what was said while ``say`` was None (before the command knows where its warnings go)
        self.held: list[str] = []
        self._catch = None
        self._warp = None

    def keep_in(self, notes: list) -> None:
        """From now on each text joins ``notes`` unless it is there already; those held so far too."""
        def keep(text: str) -> None:
            if text not in notes:
                notes.append(text)

        for text in self.held:
            keep(text)
        self.held = []
        self.say = keep

    def line(self, message, category=UserWarning) -> str:
        text = " ".join(str(message).split())
        if not issubclass(category, UserWarning):
            text += f" ({category.__name__})"
        if self.where and not issubclass(category, self.named) and not text.startswith(f"{self.where}: "):
            text = f"{self.where}: {text}"
        return text

    def _show(self, message, category, filename, lineno, file=None, line=None):
        if issubclass(category, DEVELOPER_WARNINGS):
            self._shown_before(message, category, filename, lineno, file, line)
        else:
            (self.say or self.held.append)(self.line(message, category))

    def __enter__(self) -> WarningRoute:
        self._catch = warnings.catch_warnings()
        self._catch.__enter__()
        for category in (UserWarning, RuntimeWarning):   # each said (once: the caller's), never left out
            warnings.simplefilter("always", category)
        self._shown_before = warnings.showwarning
        warnings.showwarning = self._show
        wp = sys.modules.get("warp")
        if wp is not None and hasattr(wp, "set_logger"):   # Warp prints its warnings itself: through Python's
            self._warp = wp.get_logger()
            wp.set_logger(_WarpWarnings(self._warp))
        return self

    def __exit__(self, *exc) -> None:
        if self._warp is not None:
            sys.modules["warp"].set_logger(self._warp)
            self._warp = None
        self._catch.__exit__(*exc)


class _WarpWarnings:
    """Warp's logger, its warnings given as Python warnings ("Warp: ...") for a :class:`WarningRoute`."""

    def __init__(self, logger):
        self.logger = logger

    def debug(self, message: str) -> None:
        self.logger.debug(message)

    def info(self, message: str) -> None:
        self.logger.info(message)

    def warning(self, message: str, category=None, stacklevel: int = 1) -> None:
        warnings.warn(f"Warp: {message}", category or UserWarning, stacklevel=stacklevel + 1)

    def error(self, message: str) -> None:
        self.logger.error(message)


def once(say, seen=()):
    """``say`` that says each text once (not the texts of ``seen``, said before)."""
    said = set(seen)

    def say_once(text: str) -> None:
        if text not in said:
            said.add(text)
            say(text)

    return say_once
