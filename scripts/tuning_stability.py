"""Do a board's verdicts survive a second tuning? Two or more boards of one benchmark, each from
its own independent tuning (``sim.bench PRESET --retune --tuning-seed N --design-offset F``),
evaluated on the same seeds: each board's Holm verdicts, how many agree, which starred verdicts
reverse, and each method's difference from fine-tuning over tunings and seeds, the tuning a
random effect (``sim/studies/benchmark/stability.py``).

    python scripts/tuning_stability.py BOARD BOARD [...] [--json OUT.json]
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from c2inet.errors import InputError  # noqa: E402
from sim.studies.benchmark.stability import stability, stability_markdown  # noqa: E402


def main() -> int:
    args = sys.argv[1:]
    out = None
    if "--json" in args:
        i = args.index("--json")
        if i + 1 >= len(args):
            raise InputError("--json: name the file to write")
        out, args = Path(args[i + 1]), args[:i] + args[i + 2 :]
    if len(args) < 2:
        raise InputError("give two boards or more (each its own tuning, the same seeds)")
    boards = [Path(arg) for arg in args]
    for board in boards:
        if not (board / "leaderboard.json").is_file() or not (board / "results.parquet").is_file():
            raise InputError(f"{board}: not a board (no leaderboard.json and results.parquet)")
    result = stability(boards)
    print(stability_markdown(result), end="")
    if out is not None:
        out.write_text(json.dumps(result, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    from viz.cli import run_script

    raise SystemExit(run_script(main))
