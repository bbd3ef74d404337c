"""Atomic file writes: a temporary file beside the target, renamed into place when complete.

Shared by every package (checkpoints here, figures in `viz`, outputs in `sim`), so a killed
process never leaves a half-written file under a final name.
"""

from __future__ import annotations

import errno
import hashlib
import os
import shutil
import tempfile
from collections.abc import Callable
from pathlib import Path

from c2inet.errors import CannotWrite, InputError

TEMPORARY_SUFFIX = ".c2i-tmp"  # write_atomic's temporaries: .NAME.XXXXXXXX.c2i-tmp


def write_atomic(path: Path, write: Callable[[Path], None]) -> None:
    """Call ``write(tmp)`` on a temporary file beside ``path``, then rename it into place.

    The temporary's name ends in :data:`TEMPORARY_SUFFIX`, so a resume removes the leftovers
    of an interrupted write and nothing a user named alike."""
    tmp = None
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(
            prefix=f".{path.name}.", suffix=TEMPORARY_SUFFIX, dir=path.parent
        )
        os.close(fd)
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)  # mkstemp makes 0600; give the file the usual permissions
        write(Path(tmp))
        os.replace(tmp, path)
    except (OSError, RuntimeError) as error:  # torch reports a full disk as a RuntimeError
        why = _why_unwritable(error, path.parent)
        if tmp is not None:
            Path(tmp).unlink(missing_ok=True)
        if getattr(error, "errno", None) == errno.EISDIR:  # the folder's damage, not the device's
            raise InputError(
                f"cannot write {path}: a folder stands where the file goes; move it aside"
            ) from None
        if why is None:
            raise
        raise CannotWrite(f"cannot write {path}: {why}") from None
    except BaseException:
        if tmp is not None:
            Path(tmp).unlink(missing_ok=True)
        raise


FULL = 1 << 20  # bytes free below which a failed write is put down to a full disk
CAUSES = {
    errno.ENOSPC: "no space left on its device; free some, then run again (--resume continues)",
    errno.EDQUOT: "the disk quota is spent; free some, then run again (--resume continues)",
    errno.EROFS: "its file system is read-only; choose another --out",
}


def _why_unwritable(error: BaseException, folder: Path) -> str | None:
    """What made a write fail, in words, when it is the device's doing; None otherwise."""
    code = getattr(error, "errno", None)
    if code in CAUSES:
        return CAUSES[code]
    try:
        full = shutil.disk_usage(folder).free < FULL
    except OSError:
        return None
    return CAUSES[errno.ENOSPC] if full else None


def write_text_atomic(path: Path, text: str) -> None:
    write_atomic(path, lambda tmp: tmp.write_text(text, encoding="utf-8"))


NAME_BYTES, PATH_BYTES = 255, 4096  # what Linux file systems take


def check_path_length(path: Path, option: str) -> Path:
    """``path`` itself, or an :class:`InputError` naming ``option`` where the file system
    would refuse it as too long (a name over 255 bytes, a path over 4096)."""
    text = os.fsencode(path)
    if len(text) > PATH_BYTES or any(len(part) > NAME_BYTES for part in text.split(b"/")):
        raise InputError(
            f"{option} {str(path)[:60]}...: too long for a file system (a name has at most "
            f"{NAME_BYTES} bytes, a path {PATH_BYTES})"
        )
    return path


def writable_folder(path: Path, option: str) -> Path:
    """Create folder ``path`` when missing and check that files can be written in it; an
    :class:`InputError` naming ``option`` (e.g. ``--cache``) otherwise."""
    check_path_length(path, option)
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
