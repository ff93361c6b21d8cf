"""The ``dftl-warp`` command line.

Each command lives in :mod:`dftl_warp.commands` as a module with ``add_parser(subparsers)`` and
``run(args) -> int``. A :class:`~dftl_warp.errors.UserError` ends the program with one line on
stderr and exit status 2, never a traceback; so does a bad flag (argparse's usage block is left
out: ``--help`` shows it).

Signals: SIGINT, SIGTERM and SIGHUP (what farm schedulers send) unwind the command like an
exception, so every temporary file is removed (an output being written, a PNG being saved);
the program prints one line and exits with 128 + the signal number (130, 143, 129). A batch's
checkpoints survive (they are what a resumed batch continues from). A closed stdout (``info
--json | head``, or ``>&-``) ends the program quietly with status 141 (128 + SIGPIPE); a closed
stderr (``2>&-``) loses the messages, never mixing them into stdout.
"""

from __future__ import annotations

import argparse
import importlib
import os
import signal
import sys

from .errors import UserError, WarningRoute, once

#: command modules (dftl_warp.commands.<module>), in the order ``--help`` lists them; each module's
#: ``add_parser`` chooses its subcommand's name (``import_groom`` registers ``import``)
COMMANDS = ("simulate", "render", "batch", "study", "info", "diff", "devices", "import_groom")

#: signals that end a run cleanly (temporary files removed), with exit status 128 + number
HANDLED_SIGNALS = tuple(getattr(signal, name) for name in ("SIGINT", "SIGTERM", "SIGHUP") if hasattr(signal, name))


class Terminated(KeyboardInterrupt):
    """Raised in the main thread by SIGTERM / SIGHUP / SIGINT (a KeyboardInterrupt, so code that
    cleans up after Ctrl-C cleans up after these too)."""

    def __init__(self, signum: int):
        super().__init__(signum)
        self.signum = signum

    @property
    def name(self) -> str:
        try:
            return signal.Signals(self.signum).name
        except ValueError:
            return f"signal {self.signum}"


class Parser(argparse.ArgumentParser):
    """An ArgumentParser whose errors are one line on stderr (exit status 2)."""

    def error(self, message):
        self.exit(2, f"{self.prog}: error: {message}\n")


def build_parser() -> argparse.ArgumentParser:
    from .version import __version__

    parser = Parser(
        prog="dftl-warp",
        description="GPU hair simulation (Dynamic Follow-The-Leader) and rendering with NVIDIA Warp.",
    )
    parser.add_argument("--version", action="version", version=f"dftl-warp {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=Parser)
    for name in COMMANDS:
        try:
            module = importlib.import_module(f"dftl_warp.commands.{name}")
        except ModuleNotFoundError as exc:
            if exc.name != f"dftl_warp.commands.{name}":
                raise
            continue
        module.add_parser(sub)
    return parser


#: how long a signal that came during an import waits before it is sent again, s
IMPORT_RETRY_SECONDS = 0.05


def _inside_import(frame) -> bool:
    """Whether ``frame`` (the main thread's, where a handler runs) is inside Python's import machinery."""
    while frame is not None:
        if frame.f_code.co_filename.startswith("<frozen importlib"):
            return True
        frame = frame.f_back
    return False


def _raise_terminated(signum, frame):
    if _inside_import(frame):
        # USD's module loader (pxr's Tf.PreparePythonModule) turns an exception raised while it
        # imports into a warning and goes on: the signal is sent again once the import is over
        import threading

        timer = threading.Timer(IMPORT_RETRY_SECONDS, os.kill, (os.getpid(), signum))
        timer.daemon = True
        timer.start()
        return
    for other in HANDLED_SIGNALS:  # let the clean-up finish: later signals are ignored
        signal.signal(other, signal.SIG_IGN)
    raise Terminated(signum)


def install_signal_handlers() -> dict:
    """Make SIGINT / SIGTERM / SIGHUP raise :class:`Terminated` in the main thread; returns the
    previous handlers (for :func:`restore_signal_handlers`). Does nothing off the main thread."""
    import threading

    if threading.current_thread() is not threading.main_thread():
        return {}
    previous = {}
    for signum in HANDLED_SIGNALS:
        try:
            previous[signum] = signal.signal(signum, _raise_terminated)
        except (ValueError, OSError):  # pragma: no cover
            pass
    return previous


def restore_signal_handlers(previous: dict) -> None:
    for signum, handler in previous.items():
        signal.signal(signum, handler)


def _stdout_closed() -> int:
    """The reader of stdout went away: send the rest of our output nowhere, no traceback."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        os.close(devnull)
    except (OSError, ValueError, AttributeError):
        pass
    return 128 + 13  # 128 + SIGPIPE, what a shell reports for a command killed by a closed pipe


class _ClosedStdout:
    """sys.stdout when the program was started with stdout closed (``>&-``; Python makes it None):
    a write is a reader gone (:func:`_stdout_closed`), not an AttributeError traceback."""

    def write(self, text):
        raise BrokenPipeError(32, "stdout is closed")

    def flush(self):
        pass

    def isatty(self):
        return False


def _closed_streams() -> None:
    """Started with stdout or stderr closed (``>&-``, ``2>&-``): Python sets them to None, and
    print(file=None) writes to stdout, so the messages would go out with the results. A closed
    stderr becomes os.devnull; a closed stdout raises BrokenPipeError on the first result (141)."""
    if sys.stderr is None:
        sys.stderr = open(os.devnull, "w")  # noqa: SIM115 (the program's stderr to its end)
    if sys.stdout is None:
        sys.stdout = _ClosedStdout()


def main(argv=None) -> int:
    """Entry point of the ``dftl-warp`` console script; returns the exit status."""
    from .core.devices import init_warp

    _closed_streams()
    previous = install_signal_handlers()
    try:
        # a Python warning no command routes (each routes its own, naming its file) is still one line
        with WarningRoute(once(lambda text: print(f"dftl-warp: warning: {text}", file=sys.stderr))):
            try:
                init_warp()
                parser = build_parser()
                args = parser.parse_args(argv)  # SystemExit(2) after one line for a bad flag
                args.argv = list(sys.argv[1:] if argv is None else argv)  # the command line (provenance)
                if not getattr(args, "run", None):   # no command: the help, and a failure for scripts
                    parser.print_usage(sys.stderr)
                    print("dftl-warp: error: no command given (simulate, render, info, ...)", file=sys.stderr)
                    return 2
                status = int(args.run(args) or 0)
                sys.stdout.flush()
                return status
            except UserError as exc:
                print(f"dftl-warp: error: {exc}", file=sys.stderr)
                return 2
            except Terminated as exc:
                print(f"dftl-warp: stopped by {exc.name}", file=sys.stderr)
                return 128 + exc.signum
            except KeyboardInterrupt:
                print("dftl-warp: interrupted", file=sys.stderr)
                return 130
            except BrokenPipeError:
                return _stdout_closed()
    finally:
        restore_signal_handlers(previous)


if __name__ == "__main__":
    sys.exit(main())
