"""Two boards on the same seeds whose settings differ for some methods: each of those methods
against itself, paired by seed (``sim/studies/benchmark/settings_effect.py``); pairs of boards
one after the other.

    python scripts/settings_effect.py FIRST SECOND [FIRST SECOND ...]
"""

from __future__ import annotations

import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from c2inet.errors import InputError  # noqa: E402
from sim.studies.benchmark.settings_effect import (  # noqa: E402
    settings_effect,
    settings_effect_markdown,
)


def main() -> int:
    boards = [Path(arg) for arg in sys.argv[1:]]
    if not boards or len(boards) % 2:
        raise InputError("give boards in pairs: FIRST SECOND [FIRST SECOND ...]")
    for board in boards:
        if not (board / "leaderboard.json").is_file() or not (board / "results.parquet").is_file():
            raise InputError(f"{board}: not a board (no leaderboard.json and results.parquet)")
    pairs = list(zip(boards[::2], boards[1::2], strict=True))
    results = [settings_effect(first, second) for first, second in pairs]  # all, then print
    for (first, second), result in zip(pairs, results, strict=True):
        print(f"### {first} against {second}\n")
        print(settings_effect_markdown(result))
    return 0


if __name__ == "__main__":
    from viz.cli import run_script

    raise SystemExit(run_script(main))
