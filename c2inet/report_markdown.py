"""A run's ``report.md``: how it ran, the summary tables over seeds, the collisions, the paired
comparison against fine-tuning, and each method's matrices and diagnostics."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from c2inet.metrics import COLLISION_DISTANCE, COLLISION_RADIUS
from c2inet.report import (
    POINT_RULE,
    REFERENCE,
    UNIT_NAMES,
    compare,
    comparison_rows,
    markdown_table,
    table_rows,
)

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
    if not run["quick"] and run.get("size", "full") != "full":
        kind = f"**{run['size']}**"  # below the family's sizes: not the full-size result
    seeds = (
        "**one seed** (no spread: a first look, not a result)"
        if run["seeds"] == 1
        else f"{run['seeds']} seeds per method (cells are means; ± is the std over seeds)"
    )
    parts = [
        f"Run: {kind}; {run['epochs']} epochs per task; {seeds}; best of K = {k}; "
        + (f"{run['network']}; " if run.get("network") else "")
        + f"wall time {run['wall_seconds']:.0f} s.",
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
        "C2INet's old tasks also under *c from own* (C drawn from the components that task "
        "added to the queue alone). Z is then drawn from Q(Z|X,C).",
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
    header = ["method", "Col-I primary", "Col-II primary", "Col-I all agents", "Col-II all agents"]
    keys = ("col_pred_primary", "col_truth_primary", "col_pred", "col_truth")
    bodies = any("avg_seen_col_pred_body" in m for _, m in collided)
    if bodies:
        header += ["Col-I bodies", "Col-II bodies"]
        keys += ("col_pred_body", "col_truth_body")
    rows = [header]
    rows += [
        [n, *(f"{m[f'avg_seen_{k}'][-1]:.1%}" if f"avg_seen_{k}" in m else "-" for k in keys)]
        for n, m in collided
    ]
    return [
        "",
        "Collisions of the point prediction after the last task, averaged over the tasks, as "
        "TrajNet++ defines them: a predicted path within "
        f"{COLLISION_DISTANCE:g} m (two radii of {COLLISION_RADIUS:g} m) of a neighbour's "
        "predicted path (Col-I) or true path (Col-II), at the frames and between them; of each "
        "scene's primary agent (its first, as TrajNet++ scores) and of all agents of the scenes "
        "with a neighbour; constant velocity, which ignores its neighbours, for comparison"
        + (
            "; and, where the simulator knows its bodies' size, all agents at the bodies' own "
            "contact distance (two radii of the domain)"
            if bodies
            else ""
        )
        + ":",
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
