"""Turning per-method error matrices into the paper's tables: summaries, text and Markdown."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from c2inet.metrics import (
    COLLISION_DISTANCE,
    POINT_DRAWS,
    average_seen,
    backward_transfer,
    forgetting_final,
    forgetting_worst,
)
from c2inet.significance import interval, paired

POINT_RULE = f"max(K, {POINT_DRAWS}) sampled futures"
COMPARED = ("ade", "ade_k1")  # the metrics compared over seeds (best of K, point prediction)
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
    measured = ("ade", "fde", "ade_k1", "fde_k1", "ade_draw", "fde_draw", "col_pred", "col_truth")
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


DIAGNOSTIC_COLUMNS = (
    ("probe_observed", "probe X"),
    ("probe_context", "probe context"),
    ("probe_c", "probe C"),
    ("mi_xc", "MI(X;C)"),
    ("kl_c", "KL_C"),
    ("kl_z", "KL_Z"),
    ("kl_c_binding", "KL_C binds"),
    ("c_effect", "C moves (m)"),
    ("ade_c_mean", "ADE C=mean"),
    ("ade_c_prior", "ADE C~prior"),
    ("queue_size", "queue"),
    ("ari", "ARI"),
    ("nmi", "NMI"),
    ("knob_r2", "knob R^2"),
)


def diagnostics_table(diagnostics: list[dict[str, Any]], labels: list[str]) -> str:
    """Markdown: one row per task, the columns a method has (lists averaged over seen tasks)."""

    def cell(d: dict[str, Any], key: str) -> str:
        value = d["queue"]["size"] if key == "queue_size" and "queue" in d else d.get(key)
        if isinstance(value, list):
            value = float(np.mean(value))
        return "-" if value is None else f"{value:.3g}"

    columns = [(k, t) for k, t in DIAGNOSTIC_COLUMNS if any(cell(d, k) != "-" for d in diagnostics)]
    rows = [["after", *(t for _, t in columns)]]
    rows += [
        [label, *(cell(d, k) for k, _ in columns)]
        for label, d in zip(labels, diagnostics, strict=True)
    ]
    return markdown_table(rows)


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


def markdown_report(
    scenario: str,
    labels: list[str],
    k: int,
    methods: dict[str, dict[str, Any]],
    run: dict[str, Any] | None = None,
) -> str:
    """The run's report: how it ran (``run``: quick, epochs, seeds, wall_seconds, command,
    figures, recording, unit), the Table-2-style summaries, the collisions, the paired
    comparison, then every method's matrices and diagnostics."""
    unit = (run or {}).get("unit", "m")
    parts = [f"# Continual run: `{scenario}`", "", *_how_it_ran(run, k)]
    parts += _summaries(methods, labels, k, unit)
    parts += _collisions(methods, unit)
    parts += _comparison(methods, k)
    for name, m in methods.items():
        parts += _method_section(name, m, labels, k)
    return "\n".join(parts) + "\n"


def _how_it_ran(run: dict[str, Any] | None, k: int) -> list[str]:
    """Sizes (quick and single-seed marked), the command, links to the figures and recording."""
    if run is None:
        return []
    kind = "**quick** (tiny sizes: a smoke test, not a result)" if run["quick"] else "full"
    seeds = (
        "**one seed** (no spread: a first look, not a result)"
        if run["seeds"] == 1
        else f"{run['seeds']} seeds per method (cells are means; ± is the std over seeds)"
    )
    parts = [
        f"Run: {kind}; {run['epochs']} epochs per task; {seeds}; best of K = {k}; "
        f"wall time {run['wall_seconds']:.0f} s.",
        "",
    ]
    if run.get("command"):
        parts += ["Command:", "", f"    {run['command']}", ""]
    links = [f"[{Path(f).stem}]({f})" for f in run.get("figures", [])]
    if run.get("recording"):
        links.append(f"the recording [{run['recording']}]({run['recording']}) (`rerun` opens it)")
    if links:
        parts += ["Figures and recording: " + ", ".join(links) + ".", ""]
    return parts


def _summaries(methods: dict[str, dict[str, Any]], labels: list[str], k: int, unit: str):
    """The three Table-2-style tables: best of K, the point prediction, one random draw."""
    return [
        f"Cells are ADE/FDE in {UNIT_NAMES[unit]} averaged over the tasks seen so far after "
        "each task (the paper's Table 2). Forgetting of ADE, mean over tasks but the last: "
        "*final* is the final error minus the best earlier one (Chaudhry et al. 2018), *worst* "
        "the worst error after leaving a task minus the error right after training it.",
        "",
        "The latent models (C2INet, its queue-free control, MoG, GCRL) are scored under three "
        "test-time rules for C: from the posterior Q(C|X) (their default row, GCRL's practice), "
        "*c from prior* (Eq 16 literally: C drawn from P(C), the queue's mixture) and *c from "
        "responsible* (C drawn from the queue component most responsible for the observed past); "
        "Z is then drawn from Q(Z|X,C).",
        "",
        f"Best of K = {k}, the minimum taken per scene (joint):",
        "",
        markdown_table(table_rows(methods, labels, "ade")),
        "",
        f"Point prediction (K = 1), the mean of {POINT_RULE}; a deterministic model's mean is "
        "its prediction:",
        "",
        markdown_table(table_rows(methods, labels, "ade_k1")),
        "",
        "One random draw (the first of the K samples; what K = 1 meant before the point "
        "prediction, kept for comparison):",
        "",
        markdown_table(table_rows(methods, labels, "ade_draw")),
    ]


def _collisions(methods: dict[str, dict[str, Any]], unit: str) -> list[str]:
    """Col-I and Col-II after the last task; none for a curriculum in pixels (the collision
    distance is in metres)."""
    collided = [(n, m) for n, m in methods.items() if "avg_seen_col_pred" in m and unit == "m"]
    if not collided:
        return []
    rows = [["method", "Col-I (predictions)", "Col-II (truths)"]]
    rows += [
        [n, f"{m['avg_seen_col_pred'][-1]:.1%}", f"{m['avg_seen_col_truth'][-1]:.1%}"]
        for n, m in collided
    ]
    return [
        "",
        "Collisions of the point prediction after the last task, averaged over the tasks "
        "(TrajNet++'s: the share of agents with a neighbour whose predicted path comes "
        f"within {COLLISION_DISTANCE} m of a neighbour's predicted path, Col-I, or true "
        "path, Col-II; constant velocity, which ignores its neighbours, for comparison):",
        "",
        markdown_table(rows),
    ]


def _comparison(methods: dict[str, dict[str, Any]], k: int) -> list[str]:
    """Every method against the reference, paired over the seeds, or why there is none."""
    seeds = min(m["seeds"] for m in methods.values())
    comparison = compare(methods)
    if not comparison:
        return ["", f"No paired comparison: {REFERENCE} did not run."]
    if seeds < 2:
        return ["", "No paired comparison: one seed has no spread (run `--seeds 5`)."]
    parts = [
        "",
        f"Against {REFERENCE}, paired over the same {seeds} seeds (Student's paired t-test; "
        "`*`: p < 0.05; a difference whose interval holds 0 is within the seed spread). "
        "Final average ADE after the last task, final forgetting, and the floats each "
        "method keeps between tasks:",
    ]
    for metric, title in (("ade_k1", "point prediction (K = 1)"), ("ade", f"best of {k}")):
        parts += ["", f"{title}:", "", markdown_table(comparison_rows(comparison, metric))]
    return parts


def _method_section(name: str, m: dict[str, Any], labels: list[str], k: int) -> list[str]:
    """One method's matrices, diagnostics and queue."""
    parts = ["", f"## {name} ({m['seeds']} seed(s))", ""]
    for key, title in (
        ("ade", f"ADE, best of {k}, joint"),
        ("ade_k1", "ADE, point prediction (K = 1)"),
        ("fde", f"FDE, best of {k}, joint"),
    ):
        rows = [["after \\ on", *labels]]
        for i, row in enumerate(m[key]):
            rows.append([labels[i], *("-" if v is None else f"{v:.3f}" for v in row)])
        parts += [f"{title}:", "", markdown_table(rows), ""]
    if m.get("diagnostics"):
        bound = m["diagnostics"][-1].get("mi_bound")
        mi = f"; MI in nats, at most {bound:.2f}" if bound is not None else ""
        parts += [
            "Diagnostics after each task, on the test splits of the tasks seen so far (probes: "
            "cross-validated task-id accuracy of a linear probe, from observed features, "
            f"the backbone's context and, for C2INet, C's posterior mean{mi}):",
            "",
            diagnostics_table(m["diagnostics"], labels),
            "",
        ]
    if "queue_size" in m:
        parts.append(f"Prior queue size after each task: {m['queue_size']}")
    if "pruned" in m:
        parts.append(f"Components pruned after each task: {m['pruned']}")
    return parts


def matrix_csv(matrix: list[list[float | None]], tasks: list[str]) -> str:
    lines = ["after," + ",".join(tasks)]
    for name, row in zip(tasks, matrix, strict=True):
        lines.append(name + "," + ",".join("" if v is None else f"{v:.6f}" for v in row))
    return "\n".join(lines) + "\n"
