"""Where the tuning's Optuna studies live (``--storage``): an SQLite or other database URL, or
``journal:FILE``, Optuna's journal, a file that processes on several machines may share; and
the one-line refusal of a store Optuna cannot open, given before any folder is claimed."""

from __future__ import annotations

import json
import sqlite3
from pathlib import Path
from typing import Any

import optuna
from optuna.storages import JournalStorage
from optuna.storages.journal import JournalFileBackend
from sqlalchemy.engine import make_url

from c2inet.errors import InputError
from c2inet.files import check_path_length

JOURNAL = "journal:"  # --storage journal:FILE: Optuna's journal, for writers on many machines


def storage_of(url: str) -> Any:
    """What Optuna opens for ``--storage``: Optuna's journal for ``journal:FILE`` (a file that
    processes on several machines may share; its appends are locked), else the database URL."""
    if not url.startswith(JOURNAL):
        return url
    return JournalStorage(JournalFileBackend(str(Path(url[len(JOURNAL) :]).expanduser())))


def check_storage(url: str | None, where: str | None = None) -> None:
    """Refuse, in one line, a ``--storage`` Optuna cannot open: a URL that is none, an SQLite
    file that is no database or holds another application's tables (it would gain Optuna's), a
    journal whose folder is missing or whose records are not Optuna's; nothing is claimed
    before. ``where`` names the store in the error (default: the ``--storage`` flag)."""
    if url is None:
        return
    where = where or f"--storage {url[:80]!r}"
    if url.startswith(JOURNAL):
        _check_journal(check_path_length(Path(url[len(JOURNAL) :]).expanduser(), where), where)
        return
    try:
        parsed = make_url(url)
    except Exception as error:  # SQLAlchemy's parser: whatever it raises
        raise InputError(f"{where}: not a database URL ({type(error).__name__})") from None
    if parsed.get_backend_name() == "sqlite" and parsed.database:
        path = check_path_length(Path(parsed.database), where)
        if path.exists():
            try:
                with sqlite3.connect(f"file:{path}?mode=ro", uri=True) as db:
                    rows = db.execute("SELECT name FROM sqlite_master WHERE type='table'")
                    tables = {name for (name,) in rows}
            except sqlite3.Error as error:
                raise InputError(f"{where}: {path} is no SQLite database ({error})") from None
            if tables and "studies" not in tables:
                raise InputError(f"{where}: {path} holds another application's tables")
    try:
        optuna.storages.RDBStorage(url)
    except Exception as error:  # the driver's and Optuna's: whatever they raise
        raise InputError(f"{where}: cannot be opened ({type(error).__name__})") from None


def _check_journal(path: Path, where: str) -> None:
    """A journal's folder exists; an existing journal is a file of Optuna's records (read
    without writing: a file of anything else is refused as it is)."""
    if not path.parent.is_dir():
        raise InputError(f"{where}: the folder {path.parent} does not exist")
    if not path.exists():
        return
    if not path.is_file():
        raise InputError(f"{where}: {path} is no regular file")
    try:
        with path.open("rb") as file:
            first = file.readline()
        record = json.loads(first) if first else {}
        ours = first.endswith(b"\n") and isinstance(record, dict) and "op_code" in record
        if first and not ours:  # Optuna would skip such a line, then append to the file
            raise ValueError("not a record")
        storage_of(f"{JOURNAL}{path}").get_all_studies()
    except Exception as error:  # the file, or Optuna's replay of its records: whatever it raises
        raise InputError(f"{where}: {path} is no Optuna journal ({type(error).__name__})") from None
