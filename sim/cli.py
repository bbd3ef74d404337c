"""What `sim`'s entry points share: the scenario options, workers and threads."""

from __future__ import annotations

import argparse
import os
from pathlib import Path

from viz.cli import bounded_int, plain_parser


def parser(prog: str, description: str, scenarios: bool = False) -> argparse.ArgumentParser:
    """An argument parser with the options every scenario entry point takes
    (``scenarios``: ``--scenario`` may be repeated, and gives a list)."""
    p = plain_parser(prog, description)
    p.add_argument(
        "--scenario",
        required=True,
        action="append" if scenarios else "store",
        help="curriculum, e.g. crowd_noise_0.1..0.6" + (" (repeatable)" if scenarios else ""),
    )
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
