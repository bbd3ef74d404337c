"""What the entry points share: the error guard and the scenario options."""

from __future__ import annotations

import argparse
import os
import sys
from collections.abc import Callable
from pathlib import Path

from sim.errors import InputError


class _Parser(argparse.ArgumentParser):
    def error(self, message: str):  # one line, exit 2, like every other input error
        raise InputError(f"{self.prog}: {message}")


def plain_parser(prog: str, description: str) -> argparse.ArgumentParser:
    """An argument parser whose errors are one ``InputError`` line (see :func:`guarded`)."""
    return _Parser(prog=prog, description=description)


def parser(prog: str, description: str) -> argparse.ArgumentParser:
    """An argument parser with the options every scenario entry point takes."""
    p = plain_parser(prog, description)
    p.add_argument("--scenario", required=True, help="curriculum, e.g. crowd_noise_0.1..0.6")
    p.add_argument("--seed", type=int, default=0, help="root seed (default 0)")
    p.add_argument(
        "--scenarios-dir",
        type=Path,
        action="append",
        default=[],
        help="extra folder of family TOML files (repeatable)",
    )
    return p


def bounded_int(low: int, high: int) -> Callable[[str], int]:
    """An argparse ``type``: an integer in [low, high], else a one-line usage error."""

    def convert(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not an integer") from None
        if not low <= value <= high:
            raise argparse.ArgumentTypeError(f"{value} is not between {low} and {high}")
        return value

    return convert


def add_workers(p: argparse.ArgumentParser) -> None:
    """``--workers``: processes that generate episodes in parallel (same result for any count)."""
    p.add_argument(
        "--workers",
        type=bounded_int(1, 256),
        default=os.cpu_count() or 1,
        help="worker processes for episode generation (default: the number of cores)",
    )


def add_threads(p: argparse.ArgumentParser) -> None:
    """``--threads``: torch intra-op threads. One by default: on small machines torch's default
    made the project's small models 8 to 34 times slower whenever another process ran."""
    p.add_argument(
        "--threads",
        type=bounded_int(1, 256),
        default=1,
        help="torch intra-op threads (default 1; more only helps an otherwise idle machine)",
    )


def guarded(main: Callable[[list[str] | None], int]) -> Callable[[list[str] | None], int]:
    """Run ``main``; bad input becomes one ``error:`` line on stderr and exit code 2."""

    def run(argv: list[str] | None = None) -> int:
        try:
            return main(argv)
        except InputError as error:
            print(f"error: {error}", file=sys.stderr)
            return 2

    return run
