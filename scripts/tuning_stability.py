"""Does the benchmark's tuning select? Two boards of one benchmark tuned with different seeds
(``sim.bench PRESET --tuning-seed N``), evaluated on the same seeds: per method, the final
point-prediction ADE under each tuning, their paired difference over the shared seeds with its
95 % interval, and the seed spread (the standard deviation over seeds, the larger of the two).
The issue's criterion: the difference smaller than the spread, for every method.

Given more than two boards (tunings of one benchmark), it prints instead each method's paired
difference from fine-tuning under every tuning, and whether its sign holds under all of them:
a verdict that survives the tuning's draw.

    python scripts/tuning_stability.py bench/radius-protocol bench/radius-tuning-seed-1
    python scripts/tuning_stability.py BOARD BOARD BOARD ...
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pandas as pd

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from c2inet.significance import paired  # noqa: E402


def finals(board: Path) -> dict[str, pd.Series]:
    """Per method, the final average point-prediction ADE of each evaluation seed."""
    rows = pd.read_parquet(board / "results.parquet")
    rows = rows[rows["metric"] == "ade_k1"]
    last = list(dict.fromkeys(rows["on_task"]))[-1]  # the curriculum's order
    final = rows[rows["after_task"] == last]
    means = final.groupby(["method", "seed"])["value"].mean()
    return {m: means[m] for m in means.index.get_level_values(0).unique()}


def table(a: Path, b: Path) -> str:
    first, second = finals(a), finals(b)
    lines = [
        f"Tuning A: `{a}`; tuning B: `{b}` (final K = 1 ADE, metres, the seeds both evaluated)",
        "",
        "| method | seeds | A | B | B minus A [95 % CI] | seed spread (std) | within the spread |",
        "|---|---|---|---|---|---|---|",
    ]
    for method in sorted(set(first) & set(second)):
        seeds = sorted(set(first[method].index) & set(second[method].index))
        x, y = first[method][seeds].to_numpy(), second[method][seeds].to_numpy()
        result = paired(list(y), list(x))
        spread = max(np.std(x, ddof=1), np.std(y, ddof=1)) if len(seeds) > 1 else float("nan")
        low, high = result.interval or (float("nan"), float("nan"))
        within = "yes" if abs(result.difference) < spread else "no"
        lines.append(
            f"| {method} | {len(seeds)} | {x.mean():.3f} | {y.mean():.3f} | "
            f"{result.difference:+.3f} [{low:+.3f}, {high:+.3f}] | {spread:.3f} | {within} |"
        )
    return "\n".join(lines)


def verdicts(boards: list[Path], reference: str = "finetune") -> str:
    """Each method minus ``reference`` (paired over each board's seeds) under every tuning, and
    whether its side holds under all of them (with how many intervals are clear of 0)."""
    finals_of = [finals(board) for board in boards]
    methods = sorted(set.intersection(*(set(f) for f in finals_of)) - {reference})
    names = [
        board.name if board.name not in ("A", "B") else f"{board.parent.name}/{board.name}"
        for board in boards
    ]
    lines = [
        f"Each method's final K = 1 ADE minus {reference}'s, paired over the seeds, under each "
        f"of {len(boards)} tunings (metres; `*`: the 95 % interval clear of 0)",
        "",
        "| method | " + " | ".join(names) + " | under every tuning |",
        "|---|" + "---|" * (len(boards) + 1),
    ]
    for method in methods:
        cells, differences, clear = [], [], 0
        for final in finals_of:
            seeds = sorted(set(final[method].index) & set(final[reference].index))
            result = paired(list(final[method][seeds]), list(final[reference][seeds]))
            low, high = result.interval or (0.0, 0.0)
            clear += low > 0 or high < 0
            differences.append(result.difference)
            cells.append(f"{result.difference:+.3f}{' *' if low > 0 or high < 0 else ''}")
        side = {1.0: "behind", -1.0: "ahead"}.get(float(np.sign(differences).mean()), "")
        held = f"{side} ({clear} of {len(boards)} clear of 0)" if side else "no: it changes side"
        lines.append(f"| {method} | " + " | ".join(cells) + f" | {held} |")
    return "\n".join(lines)


def main() -> int:
    if len(sys.argv) < 3:
        print(__doc__.strip().splitlines()[-1], file=sys.stderr)
        return 2
    boards = [Path(arg) for arg in sys.argv[1:]]
    print(table(*boards) if len(boards) == 2 else verdicts(boards))
    return 0


if __name__ == "__main__":
    from viz.cli import run_script

    raise SystemExit(run_script(main))
