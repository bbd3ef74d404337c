"""Atomic file writes: a temporary file beside the target, renamed into place when complete.

Shared by every package (checkpoints here, figures in `viz`, outputs in `sim`), so a killed
process never leaves a half-written file under a final name.
"""

from __future__ import annotations

import hashlib
import os
import tempfile
from collections.abc import Callable
from pathlib import Path

from c2inet.errors import InputError


def write_atomic(path: Path, write: Callable[[Path], None]) -> None:
    """Call ``write(tmp)`` on a temporary file beside ``path``, then rename it into place."""
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", dir=path.parent)
    os.close(fd)
    umask = os.umask(0)
    os.umask(umask)
    os.chmod(tmp, 0o666 & ~umask)  # mkstemp makes 0600; give the file the usual permissions
    try:
        write(Path(tmp))
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def write_text_atomic(path: Path, text: str) -> None:
    write_atomic(path, lambda tmp: tmp.write_text(text, encoding="utf-8"))


def writable_folder(path: Path, option: str) -> Path:
    """Create folder ``path`` when missing and check that files can be written in it; an
    :class:`InputError` naming ``option`` (e.g. ``--cache``) otherwise."""
    if path.exists() and not path.is_dir():
        raise InputError(f"{option} {path}: not a folder")
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as error:
        raise InputError(f"{option} {path}: cannot create it: {error.strerror}") from None
    if not os.access(path, os.W_OK | os.X_OK):
        raise InputError(f"{option} {path}: not writable")
    return path


def file_digest(path: Path) -> str:
    """The SHA-256 of a file's bytes, in hex: what a run records to know a file is unchanged."""
    with path.open("rb") as file:
        return hashlib.file_digest(file, "sha256").hexdigest()
