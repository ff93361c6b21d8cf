"""Checks on output paths made before any work is done, shared by every command that writes."""

from __future__ import annotations

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
