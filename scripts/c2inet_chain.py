"""Issue 61's chain: where does C2INet's protection of an old task fail?

Reads a sweep of C2INet-online over ``c2inet-online.oracle``, ``c2inet-online.anchor_inputs`` and
``model.c_detached`` on two-task curricula, and a run of fine-tuning on the same curricula and
seeds, and prints, per curriculum, task 1's error after task 2 (K = 1, the point prediction, and
best of 20) for fine-tuning and for every configuration under each test-time rule for C (the
posterior, the old task's own queue components; for the oracle, its own frozen component is
the true task's), each paired with fine-tuning over the seeds: the difference, its 95 % t
interval and the sign-flip p; and under each table the minimum detectable effect of its seeds.

    python scripts/c2inet_chain.py SWEEP FINETUNE_SWEEP [--out FILE.md]
"""

from __future__ import annotations

import argparse
import sys
from collections import defaultdict
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from c2inet.errors import InputError  # noqa: E402
from c2inet.files import write_text_atomic  # noqa: E402
from c2inet.significance import detectable, paired, sign_flip  # noqa: E402
from viz.cli import guarded  # noqa: E402

RULES = {"": "posterior", "_c_own": "own components"}


def task_one_after_two(folder: Path) -> dict[tuple, dict[int, float]]:
    """(scenario, method, setting, metric) -> seed -> task 1's error after task 2."""
    path = folder / "results.parquet"
    if not path.is_file():
        raise InputError(f"{folder}: no results.parquet there (a sweep's folder)")
    rows = pq.read_table(path).to_pylist()
    order: dict[str, list[str]] = defaultdict(list)  # each scenario's tasks, as trained
    for row in rows:
        if row["after_task"] not in order[row["scenario"]]:
            order[row["scenario"]].append(row["after_task"])
    found: dict[tuple, dict[int, float]] = defaultdict(dict)
    for row in rows:
        first, second, *_ = order[row["scenario"]]
        if row["after_task"] == second and row["on_task"] == first:
            key = (row["scenario"], row["method"], row["setting"] or "", row["metric"])
            found[key][int(row["seed"])] = float(row["value"])
    return found


def label(setting: str) -> str:
    """A sweep setting's name as the chain's row: oracle or queue, anchors, C's terms."""
    parts = dict(p.split("=", 1) for p in setting.split(",") if "=" in p)
    queue = "oracle" if parts.get("c2inet-online.oracle") == "True" else "queue"
    anchors = parts.get("c2inet-online.anchor_inputs", "decoded")
    detached = parts.get("model.c_detached", "True") == "True"
    return f"{queue}, {anchors} anchors, {'detached' if detached else 'connected'}"


def table(scenario: str, ours: dict, theirs: dict, metric: str) -> list[str]:
    (reference,) = [v for k, v in theirs.items() if k[0] == scenario and k[3] == metric]
    seeds = sorted(reference)
    base = [reference[s] for s in seeds]
    lines = [
        f"| configuration | rule | {metric} of task 1 after task 2 | minus fine-tuning [95 % CI] "
        "| sign-flip p |",
        "|---|---|---|---|---|",
        f"| fine-tuning | - | {np.mean(base):.3f} | | |",
    ]
    differences = []
    settings = sorted({k[2] for k in ours if k[0] == scenario})
    for setting in settings:
        for suffix, rule in RULES.items():
            values = ours.get((scenario, "c2inet-online", setting, metric + suffix))
            if values is None or sorted(values) != seeds:
                continue
            mine = [values[s] for s in seeds]
            compared = paired(mine, base)
            low, high = compared.interval or (float("nan"), float("nan"))
            differences.append(list(np.subtract(mine, base)))
            p = sign_flip(np.subtract(mine, base))
            lines.append(
                f"| {label(setting)} | {rule} | {np.mean(mine):.3f} | {compared.difference:+.3f} "
                f"[{low:+.3f}, {high:+.3f}] | {'-' if p is None else f'{p:.3f}'} |"
            )
    effect = detectable(differences)
    effect = "-" if effect is None else f"{effect:.3f} m"
    lines += ["", f"{len(seeds)} paired seeds; the smallest difference these seeds detect (80 % "
              f"power, 5 %): {effect}."]  # fmt: skip
    return lines


def report(sweep: Path, finetune: Path) -> str:
    ours, theirs = task_one_after_two(sweep), task_one_after_two(finetune)
    parts = []
    for scenario in sorted({k[0] for k in ours}):
        for metric, name in (("ade_k1", "K = 1 (the point prediction)"), ("ade", "best of 20")):
            parts += [f"## {scenario}: {name}", "", *table(scenario, ours, theirs, metric), ""]
    return "\n".join(parts)


@guarded
def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("sweep", type=Path)
    p.add_argument("finetune", type=Path)
    p.add_argument("--out", type=Path)
    args = p.parse_args(argv)
    text = report(args.sweep, args.finetune)
    if args.out:
        write_text_atomic(args.out, text)
    print(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
