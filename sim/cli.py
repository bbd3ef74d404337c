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


def parser(prog: str, description: str) -> argparse.ArgumentParser:
    """An argument parser with the options every entry point takes."""
    p = _Parser(prog=prog, description=description)
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


def add_workers(p: argparse.ArgumentParser) -> None:
    """``--workers``: processes that generate episodes in parallel (same result for any count)."""
    p.add_argument(
        "--workers",
        type=int,
        default=os.cpu_count() or 1,
        help="worker processes for episode generation (default: the number of cores)",
    )


def check_workers(workers: int) -> None:
    if not 1 <= workers <= 256:
        raise InputError(f"--workers {workers}: must be between 1 and 256")


def guarded(main: Callable[[list[str] | None], int]) -> Callable[[list[str] | None], int]:
    """Run ``main``; bad input becomes one ``error:`` line on stderr and exit code 2."""

    def run(argv: list[str] | None = None) -> int:
        try:
            return main(argv)
        except InputError as error:
            print(f"error: {error}", file=sys.stderr)
            return 2

    return run
