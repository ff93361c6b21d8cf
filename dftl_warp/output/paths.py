"""Checks on output paths made before any work is done, shared by every command that writes."""

from __future__ import annotations

import contextlib
import os
from pathlib import Path

from ..errors import UserError


def check_writable(path) -> Path:
    """``path`` as a Path; a UserError now when it could not be written: it is a directory, or
    its folder neither exists nor can be created writable, or it is a read-only file. A missing
    folder is fine when it can be created."""
    path = Path(os.fspath(path))
    if path.is_dir():
        raise UserError(f"{path}: cannot write: is a directory")
    existing = path.parent if str(path.parent) else Path(".")
    while not existing.exists() and existing != existing.parent:
        existing = existing.parent
    if not existing.is_dir():
        raise UserError(f"{path}: cannot write: folder {existing} is not a folder")
    if not os.access(existing, os.W_OK | os.X_OK):
        raise UserError(f"{path}: cannot write: folder {existing} is not writable")
    if path.exists() and not os.access(path, os.W_OK):
        raise UserError(f"{path}: cannot write: file is read-only")
    return path


def _reason(exc: OSError) -> str:
    text = exc.strerror or str(exc)
    return text[:1].lower() + text[1:]


def _nearest_folder(path: Path) -> Path:
    """The nearest folder of ``path`` that exists (its own folder, or the ancestor where the
    missing ones would be created)."""
    existing = path.parent if str(path.parent) else Path(".")
    while not existing.exists() and existing != existing.parent:
        existing = existing.parent
    return existing


def check_output(output, input_path) -> Path:
    """What ``simulate`` checks about ``output`` before any work beyond the writer's own checks
    (``check_output_path``: extension, an unwritable place, the input itself; docs/usd.md,
    "Errors"): a file actually created and removed in its folder (root passes ``os.access`` on
    read-only file systems), and :func:`check_not_a_dependency`. A UserError naming ``output``."""
    import tempfile

    output = Path(os.fspath(output))
    folder = _nearest_folder(output)
    try:
        fd, probe = tempfile.mkstemp(prefix=f".{output.name}.dftl-probe.", dir=folder)
    except OSError as exc:
        raise UserError(f"{output}: cannot write: cannot create a file in folder {folder} ({_reason(exc)})") from None
    os.close(fd)
    os.remove(probe)
    check_not_a_dependency(output, input_path)
    return output


def check_folder(folder, name: str) -> Path:
    """``folder`` as a Path; a UserError ``NAME: ...`` now, before any work, unless it is a folder
    or can be created as one, and a file can actually be created in it or in the nearest folder
    above it that exists (root passes ``os.access`` on read-only file systems and ``/proc``).
    ``name`` says where the folder comes from (``--out study``)."""
    import tempfile

    folder = Path(os.fspath(folder))
    if folder.exists() and not folder.is_dir():
        raise UserError(f"{name}: exists and is not a folder")
    existing = _nearest_folder(folder / "x")
    if not existing.is_dir():
        raise UserError(f"{name}: cannot write: {existing} is not a folder")
    try:
        fd, probe = tempfile.mkstemp(prefix=".dftl-probe.", dir=existing)
    except OSError as exc:
        raise UserError(f"{name}: cannot write: cannot create a file in folder {existing} ({_reason(exc)})") from None
    os.close(fd)
    os.remove(probe)
    return folder


def input_files(input_path) -> set[str]:
    """Real paths of the stage ``input_path`` and of every layer and asset it uses (as
    :func:`check_not_a_dependency` finds them, missing ones included); just the stage's own when
    USD cannot read it."""
    from pxr import UsdUtils

    found = {os.path.realpath(input_path)}
    delegate = UsdUtils.CoalescingDiagnosticDelegate()  # USD's warnings stay off the terminal
    try:
        layers, assets, unresolved = UsdUtils.ComputeAllDependencies(os.fspath(input_path))
    except Exception:  # noqa: BLE001 - a broken input: its own job refuses it in its own words
        return found
    finally:
        del delegate
    found.update(os.path.realpath(layer.realPath) for layer in layers if layer.realPath)
    found.update(os.path.realpath(str(p)) for p in list(assets) + list(unresolved))
    return found


def check_not_a_dependency(output, input_path) -> None:
    """A UserError when ``output`` is (by real path) a layer or asset the stage ``input_path``
    uses: a sublayer, reference, payload, value clip or other asset, found with
    ``UsdUtils.ComputeAllDependencies``, or such a layer that is missing now (writing it would
    make the input load its own output). An input USD cannot read is left to the reader."""
    from pxr import UsdUtils

    target = os.path.realpath(output)
    delegate = UsdUtils.CoalescingDiagnosticDelegate()  # USD's warnings stay off the terminal
    try:
        layers, assets, unresolved = UsdUtils.ComputeAllDependencies(os.fspath(input_path))
    except Exception:  # noqa: BLE001 - a broken input: read_scene refuses it in its own words
        return
    finally:
        del delegate
    for path in [layer.realPath for layer in layers if layer.realPath] + [str(a) for a in assets]:
        if os.path.realpath(path) == target:
            if os.path.realpath(input_path) == target:
                raise UserError(f"{output}: the output would overwrite the input")
            raise UserError(f"{output}: the output would overwrite {path}, which the input {input_path} uses")
    for path in unresolved:
        if os.path.realpath(str(path)) == target:
            raise UserError(f"{output}: the input {input_path} uses this path as a layer (missing now): "
                            f"the output would load itself")


@contextlib.contextmanager
def created_folders(output):
    """The missing folders of ``output`` created for a run (a UserError naming ``output`` when one
    cannot be), and removed again, deepest first, if the run fails while they are still empty: a
    failed run leaves no new empty folder, and never removes one that was there before or that
    holds anything (``simulate``'s :func:`output_place`, each ``batch`` job)."""
    output = Path(os.fspath(output))
    missing, created = [], []   # created: deepest first
    folder = output.parent if str(output.parent) else Path(".")
    while not folder.exists() and folder != folder.parent:
        missing.append(folder)
        folder = folder.parent
    for f in reversed(missing):
        try:
            f.mkdir()
        except FileExistsError:
            continue
        except OSError as exc:
            _remove_empty(created)
            raise UserError(f"{output}: cannot write: cannot create folder {f} ({_reason(exc)})") from None
        created.insert(0, f)
    try:
        yield
    except BaseException:
        _remove_empty(created)
        raise


@contextlib.contextmanager
def output_place(output):
    """Where ``simulate`` writes ``output``: its missing folders created (and removed again,
    when empty, if the run fails: :func:`created_folders`), the output lock held (:mod:`.lock`),
    and the partial files of killed runs removed (:func:`remove_stale_partials`)."""
    from .lock import lock_path, output_lock

    output = Path(os.fspath(output))
    with created_folders(output), output_lock(lock_path(output),
                                              message=f"{output}: another dftl-warp run is writing it"):
        remove_stale_partials(output)
        yield


def remove_stale_partials(output) -> None:
    """Remove the partial files of ``output`` (``.NAME.dftl-partial*``: a run's own, a batch job's,
    USD's text export) that runs killed with SIGKILL left behind. Called with the output's lock
    held, when no live run writes any of them; a batch's checkpoint files stay (it resumes from
    them, never from a partial file)."""
    import glob

    output = Path(os.fspath(output))
    folder = output.parent if str(output.parent) else Path(".")
    for path in folder.glob(glob.escape(f".{output.name}.dftl-partial") + "*"):
        if path.is_file() or path.is_symlink():
            with contextlib.suppress(FileNotFoundError):
                path.unlink()


def _remove_empty(folders) -> None:
    """Remove the folders (deepest first) this run created, where they are still empty."""
    for f in folders:
        try:
            f.rmdir()
        except OSError:
            return


def user_path(text: str) -> str:
    """``text`` with a leading ``~`` or ``~user`` expanded to that home folder. The shell expands
    it only in a word of its own: not in ``--out=~/x``, a quoted ``"~/x"``, a TOML file or a job
    launcher's argument list, where it made a folder literally named ``~``."""
    return os.path.expanduser(text)


def path_argument(what: str, *, file: bool = True):
    """The argparse ``type`` of every file or folder path on the command line: the text with a
    leading ``~`` expanded (:func:`user_path`), or one line for an empty (or blank) one, which
    named the current folder or nothing at all (``-o ''``: ``.: output must end in .usdc``).
    ``what`` completes "give ...": the file expected. ``file=False``: not a file (a prim path),
    only checked for being empty."""
    import argparse

    def parse(text: str) -> str:
        if not text.strip():
            raise argparse.ArgumentTypeError(f"empty path: give {what}")
        return user_path(text) if file else text

    parse.__name__ = "path"
    return parse
