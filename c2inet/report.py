"""Turning per-method error matrices into the paper's tables: summaries, text and Markdown."""

from __future__ import annotations

from typing import Any

import numpy as np

from c2inet.metrics import METRICS, average_seen, backward_transfer, forgetting


def _rounded(values) -> list[float]:
    return [round(float(v), 6) for v in values]


def _clean(array: np.ndarray) -> list:
    """Nested lists with NaN as None, for JSON."""
    return [
        [None if np.isnan(v) else round(float(v), 6) for v in row] for row in np.atleast_2d(array)
    ]


def summarise(
    runs: list[dict[str, np.ndarray]], extras: list[list[dict[str, Any]]]
) -> dict[str, Any]:
    """Mean (and std over seeds) of each matrix, with the derived continual scores of the mean."""
    out: dict[str, Any] = {"seeds": len(runs)}
    for key in METRICS:
        stack = np.stack([r[key] for r in runs])
        out[key] = _clean(stack.mean(0))
        out[f"{key}_std"] = _clean(stack.std(0))
    ade = [r["ade"] for r in runs]
    seen_ade = np.array([average_seen(m) for m in ade])
    seen_fde = np.array([average_seen(r["fde"]) for r in runs])
    out["avg_seen_ade"] = _rounded(seen_ade.mean(0))
    out["avg_seen_fde"] = _rounded(seen_fde.mean(0))
    out["avg_seen_ade_std"] = _rounded(seen_ade.std(0))
    per_task = np.mean([forgetting(m) for m in ade], 0) if len(ade[0]) > 1 else np.zeros(0)
    out["forgetting_ade_per_task"] = _rounded(per_task)
    out["forgetting_ade"] = round(float(per_task.mean()), 6) if per_task.size else 0.0
    out["backward_transfer_ade"] = round(float(np.mean([backward_transfer(m) for m in ade])), 6)
    if extras and extras[0] and "queue_size" in extras[0][0]:
        out["queue_size"] = [
            int(np.mean([e[i]["queue_size"] for e in extras])) for i in range(len(extras[0]))
        ]
    return out


def column_labels(labels: list[str]) -> list[str]:
    """``0.1 :0.2 :0.3`` as in the paper: after task i, the average over tasks seen so far."""
    return [label if i == 0 else f":{label}" for i, label in enumerate(labels)]


def table_rows(methods: dict[str, dict[str, Any]], labels: list[str]) -> list[list[str]]:
    header = ["method", *column_labels(labels), "forgetting"]
    rows = [header]
    for name, m in methods.items():
        cells = [
            f"{a:.3f}/{f:.3f}" for a, f in zip(m["avg_seen_ade"], m["avg_seen_fde"], strict=True)
        ]
        rows.append([name, *cells, f"{m['forgetting_ade']:+.3f}"])
    return rows


def text_table(methods: dict[str, dict[str, Any]], labels: list[str]) -> str:
    rows = table_rows(methods, labels)
    widths = [max(len(r[i]) for r in rows) for i in range(len(rows[0]))]
    return "\n".join("  ".join(c.rjust(w) for c, w in zip(r, widths, strict=True)) for r in rows)


def markdown_table(rows: list[list[str]]) -> str:
    lines = ["| " + " | ".join(rows[0]) + " |", "|" + "---|" * len(rows[0])]
    lines += ["| " + " | ".join(r) + " |" for r in rows[1:]]
    return "\n".join(lines)


def markdown_report(
    scenario: str, labels: list[str], k: int, methods: dict[str, dict[str, Any]]
) -> str:
    """The run's report: the Table-2-style summary, then every method's matrices."""
    parts = [
        f"# Continual run: `{scenario}`",
        "",
        f"Cells are ADE/FDE in metres, best of K = {k} with the minimum per scene (joint), "
        "averaged over the tasks seen so far after each task (the paper's Table 2). "
        "Forgetting: mean over tasks of the worst ADE after leaving a task minus the ADE "
        "right after training it.",
        "",
        markdown_table(table_rows(methods, labels)),
    ]
    for name, m in methods.items():
        parts += ["", f"## {name} ({m['seeds']} seed(s))", ""]
        for key, title in (
            ("ade", f"ADE, best of {k}, joint"),
            ("ade_k1", "ADE, one sample"),
            ("fde", f"FDE, best of {k}, joint"),
        ):
            rows = [["after \\ on", *labels]]
            for i, row in enumerate(m[key]):
                rows.append([labels[i], *("-" if v is None else f"{v:.3f}" for v in row)])
            parts += [f"{title}:", "", markdown_table(rows), ""]
        if "queue_size" in m:
            parts.append(f"Prior queue size after each task: {m['queue_size']}")
    return "\n".join(parts) + "\n"


def matrix_csv(matrix: list[list[float | None]], tasks: list[str]) -> str:
    lines = ["after," + ",".join(tasks)]
    for name, row in zip(tasks, matrix, strict=True):
        lines.append(name + "," + ",".join("" if v is None else f"{v:.6f}" for v in row))
    return "\n".join(lines) + "\n"
