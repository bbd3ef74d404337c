"""Write REPRODUCTION.md's tuned Table 2 from the committed leaderboards (``--check``: only
say whether it is up to date, exit 1 if not), so the table can never disagree with them.

    python scripts/tuned_table.py          # after committing a board under docs/leaderboards/
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from sim.studies.benchmark.board_markdown import boards_table  # noqa: E402

# the protocol's boards
BOARDS = (
    "radius-staged-all",
    "density-staged-all",
    "noise-every-draw",
    "traffic-every-draw",
    "eth-ucy",
)
START, END = "<!-- tuned-table-2: made by scripts/tuned_table.py -->", "<!-- /tuned-table-2 -->"


def table() -> str:
    folder = ROOT / "docs" / "leaderboards"
    boards = {
        name: json.loads((folder / name / "leaderboard.json").read_text())
        for name in BOARDS
        if (folder / name / "leaderboard.json").is_file()
    }
    return boards_table(boards)


def main(argv: list[str]) -> int:
    path = ROOT / "REPRODUCTION.md"
    text = path.read_text()
    if START not in text or END not in text:
        print(f"error: {path}: no {START} ... {END} block", file=sys.stderr)
        return 2
    head, rest = text.split(START, 1)
    _, tail = rest.split(END, 1)
    updated = f"{head}{START}\n{table()}{END}{tail}"
    if "--check" in argv:
        if updated != text:
            print("REPRODUCTION.md's tuned Table 2 is stale: run scripts/tuned_table.py")
            return 1
        return 0
    path.write_text(updated)
    return 0


if __name__ == "__main__":
    from viz.cli import run_script

    raise SystemExit(run_script(lambda: main(sys.argv[1:])))
