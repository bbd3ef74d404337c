"""Two runs of one curriculum, paired by seed: each method of the second against the reference of
the first (methods whose tuned settings differ run apart, e.g. ``sim.run --tuned-from radius``
one method at a time). For the final average over every task after the last, the old tasks
alone and the first task, at the point prediction (K = 1) and best of K, under every test-time
rule the second run scored (C2INet's ``c_own``): the mean of each, the paired difference (second
minus first) with its 95 % t interval and the sign-flip permutation p; and the minimum effect the
seeds detect. The runs must share their curriculum and data (their run cards' domains).

    python scripts/paired_runs.py REFERENCE_RUN METHOD_RUN [--out FILE.md]
"""

from __future__ import annotations

import argparse
import json
import sys
from collections import defaultdict
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from c2inet.errors import InputError  # noqa: E402
from c2inet.files import write_text_atomic  # noqa: E402
from c2inet.report import REFERENCE  # noqa: E402
from c2inet.significance import detectable, paired, sign_flip  # noqa: E402
from viz.cli import guarded  # noqa: E402

METRICS = {"ade_k1": "K = 1", "ade": "best of K"}
RULES = ("", "_c_own")  # the default rule, and C2INet's C from the old task's own components


def finals(run: Path) -> tuple[dict[tuple[str, str, str], dict[int, float]], list[str]]:
    """(method, metric, part) -> seed -> error after the last task, and the tasks in order."""
    path = run / "results.parquet"
    if not path.is_file():
        raise InputError(f"{run}: no results.parquet there (a finished run's folder)")
    rows = pq.read_table(path).to_pylist()
    tasks = list(dict.fromkeys(r["on_task"] for r in rows))
    cells: dict[tuple, dict[int, list[float]]] = defaultdict(lambda: defaultdict(list))
    wanted = {f"{m}{rule}" for m in METRICS for rule in RULES}
    for r in rows:
        if r["after_task"] != tasks[-1] or r["metric"] not in wanted or r["value"] is None:
            continue
        on = r["on_task"]
        parts = [
            "all tasks",
            *(["old tasks"] if on != tasks[-1] else []),
            *(["task 1"] if on == tasks[0] else []),
        ]
        for part in parts:
            cells[(r["method"], r["metric"], part)][r["seed"]].append(r["value"])
    return {
        k: {s: float(np.mean(v)) for s, v in seeds.items()} for k, seeds in cells.items()
    }, tasks


def domains(run: Path) -> list[str]:
    card = run / "run_card.json"
    if not card.is_file():
        raise InputError(f"{run}: no run_card.json there (a finished run's folder)")
    return [d.get("hash", d["name"]) for d in json.loads(card.read_text())["domains"]]


def report(first: Path, second: Path) -> str:
    if domains(first) != domains(second):
        raise InputError(f"{first} and {second}: not the same data; nothing to pair")
    (a, tasks), (b, _) = finals(first), finals(second)
    methods = sorted({k[0] for k in a})
    reference = REFERENCE if REFERENCE in methods else methods[0]
    lines = [
        f"`{second}` against `{first}` ({reference}), {len(tasks)} tasks, error after the last:",
        "",
        "| method, rule | metric | part | seeds | reference | method | difference [95 % CI] | "
        "sign-flip p |",
        "|---|---|---|---|---|---|---|---|",
    ]
    differences = []
    for (method, metric, part), values in sorted(b.items()):
        base = a.get((reference, metric.split("_c_")[0], part), {})
        seeds = sorted(set(values) & set(base))
        if len(seeds) < 2:
            continue
        x, y = [values[s] for s in seeds], [base[s] for s in seeds]
        test = paired(x, y)
        low, high = test.interval
        flip = sign_flip(np.subtract(x, y))
        differences.append(list(np.subtract(x, y)))
        rule = metric.partition("_c_")[2]
        lines.append(
            f"| {method}{', c from ' + rule if rule else ''} | "
            f"{METRICS[metric.split('_c_')[0]]} | {part} | {len(seeds)} | {np.mean(y):.4f} | "
            f"{np.mean(x):.4f} | {test.difference:+.4f} [{low:+.4f}, {high:+.4f}] | "
            f"{'-' if flip is None else f'{flip:.3f}'} |"
        )
    smallest = detectable(differences)
    lines += ["", f"The seeds detect a mean difference of {smallest:.4f} m (80 % power, the "
              "median spread of the rows)." if smallest else ""]  # fmt: skip
    return "\n".join(lines) + "\n"


@guarded
def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("reference", type=Path)
    p.add_argument("method", type=Path)
    p.add_argument("--out", type=Path, help="also write the table here")
    args = p.parse_args(argv)
    text = report(args.reference, args.method)
    print(text, end="")
    if args.out:
        write_text_atomic(args.out, text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
