"""Turning per-method error matrices into the paper's tables: summaries, text and Markdown."""

from __future__ import annotations

from typing import Any

import numpy as np

from c2inet.metrics import (
    POINT_DRAWS,
    average_seen,
    backward_transfer,
    forgetting_final,
    forgetting_worst,
)
from c2inet.significance import interval, paired

POINT_RULE = f"max(K, {POINT_DRAWS}) sampled futures"
COMPARED = ("ade", "ade_k1")  # the metrics compared over seeds (best of K, point prediction)
# what a board may rank by and its tuning score, in words: the point prediction's ADE (every
# simulated preset), or the best of K (ETH-UCY's published protocol; its learners train on the
# variety loss, whose point prediction no published model has above constant velocity)
RANKABLE = {"ade_k1": "the point prediction (K = 1)", "ade": "best of K"}
REFERENCE = "finetune"  # every method is compared with it, paired over seeds


def _rounded(values) -> list[float]:
    return [round(float(v), 6) for v in values]


def _clean(array: np.ndarray) -> list:
    """Nested lists with NaN as None, for JSON."""
    return [
        [None if np.isnan(v) else round(float(v), 6) for v in row] for row in np.atleast_2d(array)
    ]


def _bounds(pair: tuple[float, float] | None) -> list[float] | None:
    return None if pair is None else _rounded(pair)


def _forgetting(score, matrices: list[np.ndarray]) -> tuple[list[float], float]:
    """Per task (mean over seeds) and overall, of a forgetting score."""
    if len(matrices[0]) < 2:
        return [], 0.0
    per_task = np.mean([score(m) for m in matrices], 0)
    return _rounded(per_task), round(float(per_task.mean()), 6)


def summarise(
    runs: list[dict[str, np.ndarray]], extras: list[list[dict[str, Any]]]
) -> dict[str, Any]:
    """Mean (and std over seeds) of each matrix, with the derived continual scores.

    Forgetting is given twice, each named for what it is: ``forgetting_final_ade`` (Chaudhry et
    al. 2018: final error minus the best earlier one) and ``forgetting_worst_ade`` (the worst
    error after leaving a task minus the error right after training it).
    """
    out: dict[str, Any] = {"seeds": len(runs)}
    for key in runs[0]:
        stack = np.stack([r[key] for r in runs])
        out[key] = _clean(stack.mean(0))
        out[f"{key}_std"] = _clean(stack.std(0))
    # other ways the model predicts (C2INet's C from the posterior): suffixes of its metrics
    out["variants"] = [k.removeprefix("ade_k1_") for k in runs[0] if k.startswith("ade_k1_")]
    suffixes = ["", *(f"_{v}" for v in out["variants"])]
    measured = ("ade", "fde", "ade_k1", "fde_k1", "ade_draw", "fde_draw")
    measured += ("col_pred", "col_truth", "col_pred_primary", "col_truth_primary")
    measured += ("col_pred_body", "col_truth_body")
    for metric in (f"{m}{s}" for s in suffixes for m in measured if f"{m}{s}" in runs[0]):
        seen = np.array([average_seen(r[metric]) for r in runs])
        out[f"avg_seen_{metric}"] = _rounded(seen.mean(0))
        out[f"avg_seen_{metric}_std"] = _rounded(seen.std(0))
    for metric in (f"{m}{s}" for s in suffixes for m in ("ade", "ade_k1", "ade_draw")):
        matrices = [r[metric] for r in runs]
        for name, score in (("final", forgetting_final), ("worst", forgetting_worst)):
            per_task, mean = _forgetting(score, matrices)
            out[f"forgetting_{name}_{metric}_per_task"] = per_task
            out[f"forgetting_{name}_{metric}"] = mean
    out["backward_transfer_ade"] = round(
        float(np.mean([backward_transfer(r["ade"]) for r in runs])), 6
    )
    for metric in (f"{m}{s}" for s in suffixes for m in COMPARED):
        # the per-seed numbers a paired comparison needs: final average and final forgetting
        out[f"final_{metric}_per_seed"] = [round(float(np.mean(r[metric][-1])), 6) for r in runs]
        forgetting = [_forgetting(forgetting_final, [r[metric]])[1] for r in runs]
        out[f"forgetting_final_{metric}_per_seed"] = forgetting
    for key in ("queue_size", "pruned", "memory_floats"):
        if extras and extras[0] and key in extras[0][0]:
            out[key] = [int(np.mean([e[i][key] for e in extras])) for i in range(len(extras[0]))]
    return out


def compare(
    methods: dict[str, dict[str, Any]], reference: str = REFERENCE
) -> dict[str, dict[str, Any]]:
    """Every method (and test-time rule) against ``reference`` on the same seeds: final average
    error and final forgetting, each with its mean, 95 % interval, the paired difference, its
    interval and p-value. Empty when ``reference`` did not run."""
    if reference not in methods:
        return {}
    base = methods[reference]
    out: dict[str, dict[str, Any]] = {}
    for name, m in methods.items():
        for variant in ["", *m.get("variants", [])]:
            row: dict[str, Any] = {}
            for metric in COMPARED:
                key = f"{metric}_{variant}" if variant else metric
                for score in ("final", "forgetting_final"):
                    mine, theirs = m[f"{score}_{key}_per_seed"], base[f"{score}_{metric}_per_seed"]
                    test = paired(mine, theirs)
                    row[f"{score}_{metric}"] = {
                        "mean": round(float(np.mean(mine)), 6),
                        "interval": _bounds(interval(mine)),
                        "difference": round(test.difference, 6),
                        "difference_interval": _bounds(test.interval),
                        "p_value": None if test.p_value is None else round(test.p_value, 6),
                        "significant": test.significant,
                    }
            row["memory_floats"] = m.get("memory_floats", [0])[-1]  # after the last task
            out[f"{name}, {variant.replace('_', ' from ', 1)}" if variant else name] = row
    return out


def comparison_rows(comparison: dict[str, dict[str, Any]], metric: str) -> list[list[str]]:
    """The Markdown rows of :func:`compare` for one metric; ``*`` marks p < 0.05."""

    def cell(entry: dict[str, Any], signed: bool = False) -> str:
        low_high = entry["difference_interval" if signed else "interval"]
        value = entry["difference" if signed else "mean"]
        form = "+.3f" if signed else ".3f"
        text = format(value, form)
        if low_high is None:
            return text
        return f"{text} [{format(low_high[0], form)}, {format(low_high[1], form)}]"

    header = [
        "method",
        "final avg [95 % CI]",
        f"vs {REFERENCE} [95 % CI]",
        "p",
        "forgetting final [95 % CI]",
        "memory (floats)",
    ]
    rows = [header]
    for name, row in comparison.items():
        final, forget = row[f"final_{metric}"], row[f"forgetting_final_{metric}"]
        p = final["p_value"]
        mark = "" if p is None else f"{p:.3f}" + (" *" if final["significant"] else "")
        memory = f"{row['memory_floats']:,}"
        rows.append([name, cell(final), cell(final, True), mark or "-", cell(forget), memory])
    return rows


def column_labels(labels: list[str]) -> list[str]:
    """``0.1 :0.2 :0.3`` as in the paper: after task i, the average over tasks seen so far."""
    return [label if i == 0 else f":{label}" for i, label in enumerate(labels)]


def table_rows(
    methods: dict[str, dict[str, Any]], labels: list[str], metric: str = "ade"
) -> list[list[str]]:
    """One row per method (and per variant, e.g. C2INet with C from the posterior): ADE/FDE
    averaged over seen tasks after each task, then forgetting.

    ``metric`` ``ade`` gives best of K, ``ade_k1`` the point prediction, ``ade_draw`` one random
    draw. A row that ends above constant velocity's final average (when ``cv`` ran) says so.
    """
    header = ["method", *column_labels(labels), "forgetting final", "forgetting worst"]
    rows = [header]
    floor = methods["cv"][f"avg_seen_{metric}"][-1] if "cv" in methods else float("inf")
    for name, m in methods.items():
        for variant in ["", *m.get("variants", [])]:
            key = f"{metric}_{variant}" if variant else metric
            fde = key.replace("ade", "fde", 1)
            stds = m[f"avg_seen_{key}_std"] if m["seeds"] > 1 else [None] * len(labels)
            cells = [
                f"{a:.3f}" + ("" if s is None else f"±{s:.3f}") + f"/{f:.3f}"
                for a, s, f in zip(m[f"avg_seen_{key}"], stds, m[f"avg_seen_{fde}"], strict=True)
            ]
            final, worst = m[f"forgetting_final_{key}"], m[f"forgetting_worst_{key}"]
            label = f"{name}, {variant.replace('_', ' from ', 1)}" if variant else name
            if m[f"avg_seen_{key}"][-1] > floor:
                label += " (worse than cv)"
            rows.append([label, *cells, f"{final:+.3f}", f"{worst:+.3f}"])
    return rows


def summarise_diagnostics(runs: list[list[dict[str, Any]]]) -> list[dict[str, Any]]:
    """Per task, the mean over seeds of every numeric diagnostic (lists element-wise); the
    queue's details are the first seed's."""
    out = []
    for per_seed in zip(*runs, strict=True):
        merged: dict[str, Any] = {}
        for key, first in per_seed[0].items():
            values = [d.get(key) for d in per_seed]
            if key == "queue" or any(v is None for v in values):
                merged[key] = first
            elif isinstance(first, list):
                merged[key] = _rounded(np.mean(values, axis=0))
            else:
                merged[key] = round(float(np.mean(values)), 4)
        out.append(merged)
    return out


UNIT_NAMES = {"m": "metres", "px": "pixels"}


def caption(k: int, seeds: int, metric: str = "ade", unit: str = "m") -> str:
    """What the cells of :func:`table_rows` are, in a sentence."""
    samples = f"best of K = {k} samples, the minimum taken per scene (joint)"
    if metric == "ade_k1":
        samples = f"the point prediction (K = 1: the mean of {POINT_RULE})"
    elif metric == "ade_draw":
        samples = "one random draw (the first of the K samples)"
    spread = f"mean ± std of ADE over {seeds} seeds" if seeds > 1 else "one seed"
    return (
        f"ADE/FDE in {UNIT_NAMES[unit]}, {samples}, averaged over the tasks seen so far after "
        f"each task ({spread}); forgetting of ADE in {UNIT_NAMES[unit]} (final: final minus best "
        "earlier error; "
        "worst: worst error after leaving a task minus the error right after it)."
    )


def text_table(methods: dict[str, dict[str, Any]], labels: list[str]) -> str:
    rows = table_rows(methods, labels)
    widths = [max(len(r[i]) for r in rows) for i in range(len(rows[0]))]
    return "\n".join("  ".join(c.rjust(w) for c, w in zip(r, widths, strict=True)) for r in rows)


def markdown_table(rows: list[list[str]]) -> str:
    lines = ["| " + " | ".join(rows[0]) + " |", "|" + "---|" * len(rows[0])]
    lines += ["| " + " | ".join(r) + " |" for r in rows[1:]]
    return "\n".join(lines)


def matrix_csv(matrix: list[list[float | None]], tasks: list[str]) -> str:
    lines = ["after," + ",".join(tasks)]
    for name, row in zip(tasks, matrix, strict=True):
        lines.append(name + "," + ",".join("" if v is None else f"{v:.6f}" for v in row))
    return "\n".join(lines) + "\n"
