"""What every entry point shares: an argument parser whose errors are one line, and the guard.

It lives in `viz`, the lowest floor with entry points (`viz.serve`, `viz.screenshot`); `sim`'s
command lines build on it.
"""

from __future__ import annotations

import argparse
import os
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

from c2inet.errors import CannotWrite, InputError, WorkerDied, one_line


class _Parser(argparse.ArgumentParser):
    def error(self, message: str):  # one line, exit 2, like every other input error
        raise InputError(f"{self.prog}: {message}")


def plain_parser(prog: str, description: str) -> argparse.ArgumentParser:
    """An argument parser whose errors are one ``InputError`` line (see :func:`guarded`); the
    description may be a docstring's first line, whose reST quotes are dropped."""
    return _Parser(prog=prog, description=description.replace("``", ""))


def _bounded(kind: type, what: str, low: float, high: float) -> Callable[[str], Any]:
    def convert(text: str):
        try:
            value = kind(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not {what}") from None
        if not low <= value <= high:  # NaN is in no range
            bounds = (low, high) if kind is int else (f"{low:g}", f"{high:g}")
            raise argparse.ArgumentTypeError(f"{text} is not between {bounds[0]} and {bounds[1]}")
        return value

    return convert


def bounded_int(low: int, high: int) -> Callable[[str], int]:
    """An argparse ``type``: an integer in [low, high], else a one-line usage error."""
    return _bounded(int, "an integer", low, high)


def bounded_float(low: float, high: float) -> Callable[[str], float]:
    """An argparse ``type``: a number in [low, high], else a one-line usage error."""
    return _bounded(float, "a number", low, high)


def guarded(main: Callable[..., int]) -> Callable[..., int]:
    """Run ``main`` (its command line first, then what else it takes); bad input becomes one
    ``error:`` line on stderr and exit code 2."""

    def run(argv: list[str] | None = None, *more: Any) -> int:
        try:
            return main(argv, *more)
        except InputError as error:
            print(f"error: {one_line(str(error))}", file=sys.stderr)
            return 2
        except (WorkerDied, CannotWrite) as error:
            print(f"error: {one_line(str(error))}", file=sys.stderr)
            return 1
        except BrokenPipeError:  # the reader left (| head): stop quietly, as a shell tool does
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
            return 0

    return run


def run_script(main: Callable[[], Any]) -> int:
    """A script's entry (``scripts/``, ``benchmarks/``): bad input, a file it cannot read or a
    value it cannot take is one ``error:`` line and exit 2, never a traceback
    (``C2I_TRACEBACK=1`` shows it, for a bug)."""
    try:
        result = main()
    except InputError as error:
        print(f"error: {one_line(str(error))}", file=sys.stderr)
        return 2
    except (OSError, ValueError, KeyError, TypeError) as error:
        if os.environ.get("C2I_TRACEBACK"):
            raise
        print(f"error: {type(error).__name__}: {one_line(str(error))[:300]}", file=sys.stderr)
        return 2
    return result if isinstance(result, int) else 0


def config_path(argv: list[str]) -> Path | None:
    """The ``--config FILE`` of a command line, read as the command's own parser reads it."""
    early = argparse.ArgumentParser(add_help=False)
    early.add_argument("--config", type=Path)
    return early.parse_known_args(argv)[0].config
