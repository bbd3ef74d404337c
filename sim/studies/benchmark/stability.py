"""Do a board's verdicts survive a second tuning? Two or more boards of one benchmark, each from
its own independent tuning, evaluated on the same seeds: each board's Holm verdicts side by
side, how many agree, which starred verdicts reverse, and each method's difference from
fine-tuning over tunings and seeds together, the tuning a random effect
(:func:`c2inet.significance.over_tunings`), Holm-adjusted over the methods. A verdict that holds
is one whose over-tunings interval is clear of 0; a board that rests on one tuning cannot say.
Beside it, each board's seed ceiling: how often two boards of that one tuning would agree if
they differed only in their seeds, which bounds what any second tuning can be expected to reach.

``python scripts/tuning_stability.py BOARD BOARD ...`` prints it."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from c2inet.lazy import lazy_module
from c2inet.report import REFERENCE
from c2inet.significance import (
    ALPHA,
    LEVEL,
    holm,
    over_tunings,
    paired,
    replication_agreement,
)

# loaded on first use: a command that stops at bad input or answers --help does not pay for it
pq = lazy_module("pyarrow.parquet")


def finals(board: Path, metric: str = "ade_k1") -> dict[str, dict[int, float]]:
    """Per method, each evaluation seed's final average ADE on ``metric`` (the board's: the
    point prediction's or best of K; the mean over every task after the curriculum's last)."""
    columns = ["method", "seed", "on_task", "after_task", "value"]
    table = pq.read_table(
        board / "results.parquet", columns=columns, filters=[("metric", "==", metric)]
    ).to_pydict()  # only the cells of the metric: a board holds every metric's, 0.5 M values
    last = list(dict.fromkeys(table["on_task"]))[-1]  # the curriculum's order
    cells: dict[str, dict[int, list[float]]] = {}
    for method, seed, after, value in zip(
        table["method"], table["seed"], table["after_task"], table["value"], strict=True
    ):
        if after == last:
            cells.setdefault(method, {}).setdefault(seed, []).append(value)
    return {
        m: {s: float(np.mean(v)) for s, v in sorted(seeds.items())} for m, seeds in cells.items()
    }


def verdict(entry: dict[str, Any], metric: str = "ade_k1") -> str:
    """``ahead``, ``behind`` (of fine-tuning, Holm-significant on ``metric``) or ``level``."""
    cell = entry[f"final_{metric}"]
    if not cell.get("significant"):
        return "level"
    return "ahead" if cell["difference"] < 0 else "behind"


def stability(boards: list[Path], reference: str = REFERENCE) -> dict[str, Any]:
    """Compare the boards' verdicts and pool them over tunings (see the module's docstring)."""
    if len(boards) < 2:
        raise ValueError("stability: two boards or more, each its own tuning")
    metas = [json.loads((b / "leaderboard.json").read_text()) for b in boards]
    metrics = {m.get("metric", "ade_k1") for m in metas}
    if len(metrics) != 1:
        raise ValueError(f"stability: the boards rank different metrics ({', '.join(metrics)})")
    metric = metrics.pop()
    values = [finals(b, metric) for b in boards]
    entries = [{e["method"]: e for e in meta["entries"]} for meta in metas]
    methods = sorted(set.intersection(*(set(e) for e in entries)) - {reference})
    rows, pooled = {}, []
    for method in methods:
        seeds = sorted(set.intersection(*(set(v[method]) & set(v[reference]) for v in values)))
        differences = [[v[method][s] - v[reference][s] for s in seeds] for v in values]
        pooled.append(over_tunings(differences))
        rows[method] = {
            "seeds": len(seeds),
            "verdicts": [verdict(e[method], metric) for e in entries],
            "differences": [round(e[method][f"final_{metric}"]["difference"], 6) for e in entries],
            "p_holm": [e[method][f"final_{metric}"]["p_value"] for e in entries],
            "tunings_differ": _tunings_differ(differences),
        }
    for method, result, p in zip(methods, pooled, holm([r.p_value for r in pooled]), strict=True):
        clear = result.interval[0] > 0 or result.interval[1] < 0
        rows[method]["over_tunings"] = {
            "difference": round(result.difference, 6),
            "interval": [round(x, 6) for x in result.interval],
            "df": round(result.df, 1),
            "p_holm": round(p, 6),
            "holds": ("ahead" if result.difference < 0 else "behind")
            if clear and p < ALPHA
            else "not shown",
        }
    agree = [m for m in methods if len(set(rows[m]["verdicts"])) == 1]
    ceilings = [seed_ceiling(v, methods, reference) for v in values]
    reversed_ = [m for m in methods if {"ahead", "behind"} <= set(rows[m]["verdicts"])]
    return {
        "boards": [str(b) for b in boards],
        "tunings": len(boards),
        "reference": reference,
        "methods": rows,
        "agree": len(agree),
        "ranked": len(methods),
        "reversed": reversed_,
        "level": LEVEL,
        "seed_ceiling": ceilings,
    }


def seed_ceiling(
    values: dict[str, dict[int, float]], methods: list[str], reference: str
) -> dict[str, Any]:
    """How often two boards of this one tuning would agree on a Holm verdict if they differed
    only in their seeds, this board's differences taken as the truth
    (:func:`c2inet.significance.replication_agreement`): at its seed count and at twice it."""
    seeds = sorted(set.intersection(*(set(values[m]) for m in [*methods, reference])))
    d = [[values[m][s] - values[reference][s] for s in seeds] for m in methods]
    n = len(seeds)
    return {
        "seeds": n,
        "agree": replication_agreement(d),
        "agree_twice": replication_agreement(d, 2 * n),
    }


def _tunings_differ(differences: list[list[float]]) -> str:
    """Two tunings' settings compared on the same seeds: the paired difference of the method's
    own gap from fine-tuning between the first two tunings, with its interval."""
    first, second = np.asarray(differences[0]), np.asarray(differences[1])
    test = paired(list(second), list(first))
    low, high = test.interval or (float("nan"), float("nan"))
    return f"{test.difference:+.3f} [{low:+.3f}, {high:+.3f}]"


def stability_markdown(result: dict[str, Any]) -> str:
    """The comparison as Markdown: a row a method, then the agreement in one line."""
    names = [  # a board in A/ and B/ folders is named with its parent
        Path(b).name if len(Path(b).name) > 1 else f"{Path(b).parent.name}/{Path(b).name}"
        for b in result["boards"]
    ]
    ref = result["reference"]
    lines = [
        f"Each ranked method's final K = 1 ADE minus {ref}'s under {result['tunings']} "
        "independent tunings evaluated on the same seeds: each board's difference and Holm "
        "verdict, then the difference over tunings and seeds with the tuning a random effect "
        f"({round(100 * result['level'])} % interval, Satterthwaite's df, Holm over the methods).",
        "",
        "| method | seeds | "
        + " | ".join(f"`{n}`" for n in names)
        + " | 2nd minus 1st tuning [95 % CI] | over tunings [95 % CI] | df | Holm p | holds |",
        "|---|---|" + "---|" * len(names) + "---|---|---|---|---|",
    ]
    for method, row in result["methods"].items():
        cells = [
            f"{d:+.3f} ({v})" for d, v in zip(row["differences"], row["verdicts"], strict=True)
        ]
        over = row["over_tunings"]
        low, high = over["interval"]
        lines.append(
            f"| {method} | {row['seeds']} | " + " | ".join(cells) + f" | {row['tunings_differ']} "
            f"| {over['difference']:+.3f} [{low:+.3f}, {high:+.3f}] | {over['df']:g} | "
            f"{over['p_holm']:.3f} | {over['holds']} |"
        )
    share = result["agree"] / max(result["ranked"], 1)
    lines += [
        "",
        f"Holm verdicts agree for {result['agree']} of {result['ranked']} ranked methods "
        f"({100 * share:.0f} %); starred verdicts reversed: "
        + (", ".join(result["reversed"]) or "none")
        + ".",
        "",
        "Seed noise alone: two boards of one of these tunings that differed only in their seeds "
        "(its own differences taken as the truth, seeds resampled, 2,000 pairs) would agree on "
        + ", ".join(
            f"{100 * c['agree']:.0f} % (`{name}`, {c['seeds']} seeds; {100 * c['agree_twice']:.0f} "
            f"% at {2 * c['seeds']})"
            for name, c in zip(names, result["seed_ceiling"], strict=True)
        )
        + " of the verdicts: what a second tuning that changed nothing would reach, expected.",
    ]
    return "\n".join(lines) + "\n"
