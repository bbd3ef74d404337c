"""The project's error types the entry points print as one line: bad input (exit 2) and a job
process that died (exit 1).

They live in the learner, the lowest floor, so `viz` and `sim` share them without importing
upwards."""

from __future__ import annotations

import difflib
from collections.abc import Iterable


class WorkerDied(RuntimeError):
    """A job's worker process ended without a result: killed, out of memory, or unable to start
    (the message says which are possible and what to do)."""


class CannotWrite(Exception):
    """An output file could not be written: its device is full or read-only, or the quota is
    spent (the message names the file and the way out)."""


class InputError(ValueError):
    """Bad user input (scenario, family TOML, knob value, data file, option).

    The message names the input and what is wrong; it is shown to the user as is.
    """


def did_you_mean(name: str, known: Iterable[str]) -> str:
    """``"; did you mean 'x'?"`` for the closest known name (the names that begin with
    ``name`` first: ``c2inet`` means a C2INet, not ``pecnet``), or nothing when none is close."""
    known = list(known)
    starting = sorted(k for k in known if name and k.startswith(name))
    if starting:
        return f"; did you mean {' or '.join(repr(k) for k in starting[:3])}?"
    close = difflib.get_close_matches(name, known, n=1, cutoff=0.6)
    return f"; did you mean {close[0]!r}?" if close else ""


def quote(text: str, limit: int = 60) -> str:
    """``repr`` of ``text``, cut to its first ``limit`` characters: error messages quote what a
    user wrote (a scenario, a line of a data file) without repeating all of it."""
    return repr(text) if len(text) <= limit else f"{text[:limit]!r}... ({len(text)} characters)"


def one_line(text: str) -> str:
    """``text`` with every unprintable character (a newline, a control code) escaped, so an
    error message stays one line whatever the input it quotes."""
    return "".join(c if c.isprintable() else repr(c)[1:-1] for c in text)
