"""Which predictions collide? Col-I (two predicted agents closer than their radii) and Col-II (a
prediction against a neighbour's true path) of the point prediction after the last task, beside
its ADE, from committed leaderboards' ``results.parquet``: mean and standard deviation over the
evaluation seeds, each seed's value averaged over the tasks.

    python scripts/collision_table.py docs/leaderboards/density [more boards] [--methods cv,...]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import pandas as pd

METRICS = {"ade_k1": "ADE K = 1 (m)", "col_pred": "Col-I", "col_truth": "Col-II"}


def final_rows(board: Path) -> pd.DataFrame:
    """Per method and seed, each metric after the curriculum's last task, averaged over tasks."""
    rows = pd.read_parquet(board / "results.parquet")
    last = list(dict.fromkeys(rows["on_task"]))[-1]  # the curriculum's order, not the names'
    final = rows[(rows["after_task"] == last) & rows["metric"].isin(list(METRICS))]
    return final.groupby(["method", "seed", "metric"])["value"].mean().unstack("metric")


def table(board: Path, methods: list[str] | None) -> str:
    per_seed = final_rows(board)
    summary = per_seed.groupby("method").agg(["mean", "std"])
    order = methods or summary.sort_values(("ade_k1", "mean")).index.tolist()
    lines = [
        f"`{board}`",
        "",
        "| method | seeds | " + " | ".join(METRICS.values()) + " |",
        "|---|---|" + "---|" * len(METRICS),
    ]
    for method in (m for m in order if m in summary.index):
        cells = [
            f"{summary.loc[method, (k, 'mean')]:.3f} ± {summary.loc[method, (k, 'std')]:.3f}"
            for k in METRICS
        ]
        seeds = len(per_seed.loc[method])
        lines.append(f"| {method} | {seeds} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("boards", nargs="+", type=Path)
    p.add_argument("--methods", help="comma-separated, in this order (default: all, by ADE)")
    args = p.parse_args()
    methods = args.methods.split(",") if args.methods else None
    print("\n\n".join(table(board, methods) for board in args.boards))


if __name__ == "__main__":
    from viz.cli import run_script

    raise SystemExit(run_script(main))
