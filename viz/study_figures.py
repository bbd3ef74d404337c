"""The studies' and the benchmark's figures as PNGs: the active curriculum, drift, fidelity,
shift, the paper's ablations and orders, and the leaderboard."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from viz.colours import as_matplotlib, method_colour
from viz.figures import plt, save_figure


def active_figure(report: dict[str, Any], path: Path) -> None:
    """Mean and worst held-out ADE against scenes simulated, and the final error per grid value,
    one line per strategy."""
    fig, axes = plt.subplots(1, 3, figsize=(15, 3.8))
    for i, (name, s) in enumerate(report["strategies"].items()):
        colour = as_matplotlib(method_colour(i))
        for ax, key in zip(axes[:2], ("mean", "worst"), strict=True):
            ax.errorbar(
                report["scenes"], s[key], s[f"{key}_std"], fmt="-o", ms=3, capsize=2, label=name,
                color=colour,
            )  # fmt: skip
        axes[2].plot(report["grid"], s["final_errors"], "-o", ms=3, label=name, color=colour)
    axes[0].set(xlabel="scenes simulated", ylabel="mean held-out ADE (m)")
    axes[1].set(xlabel="scenes simulated", ylabel="worst held-out ADE (m)")
    axes[2].set(xlabel=report["knob"], ylabel="final held-out ADE (m)")
    axes[0].legend(fontsize=7)
    fig.suptitle(f"active curriculum on {report['family']} ({report['method']})", fontsize=10)
    fig.tight_layout()
    save_figure(fig, path)


def drift_figure(report: dict[str, Any], path: Path) -> None:
    """Left: mean probe ADE over the stream per method, boundaries marked. Right: each
    method's error-over-time matrix, as each probe's excess over its best (forgetting shows as
    colour returning down a column)."""
    methods = report["methods"]
    fig, axes = plt.subplots(1, 1 + len(methods), figsize=(5 + 3.6 * len(methods), 3.8))
    values = report["chunk_values"]
    ax = axes[0]
    for i, (name, m) in enumerate(methods.items()):
        colour = as_matplotlib(method_colour(i))
        ax.plot(values, np.mean(m["ade"], axis=1), "-o", ms=3, label=name, color=colour)
        for c in m["given"][1:]:
            ax.axvline(values[c], color=colour, alpha=0.25, lw=1)
    ax.set(xlabel=f"{report['knob']} at the stream's position", ylabel="mean probe ADE (m)")
    ax.set_title(f"boundaries: {report['boundaries']}", fontsize=9)
    ax.legend(fontsize=7)
    relative = {
        name: np.asarray(m["ade"]) / np.min(m["ade"], axis=0) - 1 for name, m in methods.items()
    }
    top = max(100 * r.max() for r in relative.values())
    for ax, name in zip(axes[1:], methods, strict=True):
        image = ax.imshow(100 * relative[name], aspect="auto", cmap="magma_r", vmin=0, vmax=top)
        ax.set_xticks(range(len(report["probes"])), [f"{v:g}" for v in report["probes"]])
        ax.set_yticks(range(len(values)), [f"{v:.2f}" for v in values], fontsize=6)
        ax.set(xlabel="probe", ylabel="after the chunk at")
        ax.set_title(name, fontsize=9)
    fig.colorbar(image, ax=axes[-1], label="ADE above the probe's best (%)")
    fig.suptitle(f"drift of {report['family']}", fontsize=10)
    fig.tight_layout()
    save_figure(fig, path)


def fidelity_figure(report: dict[str, Any], path: Path) -> None:
    """Top: relative difference of each statistic per pair (the tolerance shaded), transfer
    errors per pair, and the whole transfer matrix. Bottom: per-scene histograms of each
    distribution, generated solid and reference dashed, one colour per pair."""
    pairs = report["pairs"]
    x = np.arange(len(pairs))
    labels = [p["domains"][0].rsplit("_", 1)[-1] for p in pairs]
    colours = plt.get_cmap("viridis")(np.linspace(0, 0.9, len(pairs)))
    fig, axes = plt.subplots(2, 4, figsize=(18, 8))
    ax = axes[0, 0]
    ax.axhspan(-100 * report["tolerance"], 100 * report["tolerance"], color="0.9")
    for name in pairs[0]["relative"]:
        ax.plot(x, [100 * p["relative"][name] for p in pairs], "-o", label=name)
    ax.set(xticks=x, xticklabels=labels, ylabel="generated vs reference (%)")
    ax.set_title("realised statistics", fontsize=9)
    ax.legend(fontsize=7)
    ax = axes[0, 1]
    if "transfer" in report:
        for key, style, label in (
            ("generated_on_reference", "-o", "trained on generated"),
            ("reference_on_reference", "-s", "trained on reference"),
            ("cv_on_reference", ":^", "constant velocity"),
        ):
            ax.plot(x, [p["transfer"][key] for p in pairs], style, label=label)
        ax.set(xticks=x, xticklabels=labels, ylabel="ADE on the reference (m)")
        ax.legend(fontsize=7)
        ax = axes[0, 2]
        matrix = np.asarray(report["transfer"]["ade"])
        image = ax.imshow(matrix, cmap="magma_r")
        ticks = [
            t.rsplit("_", 1)[0][:12] + " " + t.rsplit("_", 1)[-1]
            for t in report["transfer"]["tasks"]
        ]
        ax.set_xticks(range(len(ticks)), ticks, rotation=90, fontsize=6)
        ax.set_yticks(range(len(ticks)), ticks, fontsize=6)
        ax.set(xlabel="tested on", ylabel="trained on")
        fig.colorbar(image, ax=ax, label="ADE (m)")
    axes[0, 1].set_title("transfer to the reference", fontsize=9)
    axes[0, 2].set_title("transfer matrix", fontsize=9)
    legend = axes[0, 3]  # the key to the histograms below
    for label, colour in zip(labels, colours, strict=True):
        legend.plot([], [], color=colour, label=f"pair {label}")
    legend.plot([], [], "k-", label="generated")
    legend.plot([], [], "k--", label="reference")
    legend.legend(loc="center", fontsize=8, title="histograms below", title_fontsize=8)
    legend.axis("off")
    for ax, name in zip(axes[1], pairs[0]["histograms"], strict=True):
        for pair, colour in zip(pairs, colours, strict=True):
            histogram = pair["histograms"][name]
            if histogram is None:
                continue
            for side, style in (("generated", "-"), ("reference", "--")):
                ax.stairs(histogram[side], histogram["edges"], color=colour, linestyle=style)
        ax.set_title(f"per-scene {name.replace('_', ' ')}", fontsize=9)
        ax.set_ylabel("scenes")
    fig.suptitle(f"{report['scenario']} against {report['reference']}", fontsize=10)
    fig.tight_layout()
    save_figure(fig, path)


def shift_figure(summary: dict[str, Any], path: Path) -> None:
    """Per family (columns): forgetting against the knob shift, against the statistics
    distance, and the transfer gap against the knob shift (rows), one line per method."""
    families = summary["families"]
    fig, axes = plt.subplots(3, len(families), figsize=(4.6 * len(families), 9), squeeze=False)
    for column, family in enumerate(families):
        rows = family["rows"]
        for i, method in enumerate(summary["methods"]):
            colour = as_matplotlib(method_colour(i))
            lost = [r["methods"][method]["forgetting"] for r in rows]
            spread = [r["methods"][method]["forgetting_std"] for r in rows]
            gap = [r["methods"][method]["gap"] for r in rows]
            shifts = [r["knob_shift"] for r in rows]
            distance = [r["statistics_distance"] for r in rows]
            axes[0, column].errorbar(
                shifts, lost, spread, fmt="-o", ms=3, capsize=2, label=method, color=colour
            )
            order = np.argsort(distance)
            axes[1, column].plot(
                np.take(distance, order), np.take(lost, order), "-o", ms=3, color=colour
            )
            axes[2, column].plot(shifts, gap, "-o", ms=3, color=colour)
        axes[0, column].set_title(f"{family['family']} from {family['base']:g}", fontsize=9)
        axes[0, column].set(xlabel=f"{family['knob']} shift", ylabel="forgetting (m)")
        axes[1, column].set(xlabel="realised-statistics distance", ylabel="forgetting (m)")
        axes[2, column].set(xlabel=f"{family['knob']} shift", ylabel="transfer gap (m)")
        for ax in axes[:, column]:
            ax.axhline(0, color="0.7", lw=0.8)
    axes[0, 0].legend(fontsize=7)
    fig.tight_layout()
    save_figure(fig, path)


def study_figure(summary: dict, path: Path) -> None:
    """Final average ADE (solid) and FDE (dashed) per variant or per order, one panel per
    curriculum (variants) or per family (orders)."""
    rows = summary["rows"]
    groups: dict[str, list[dict]] = {}
    for r in rows:
        key = r["scenario"].rsplit("_", 1)[0] if summary.get("by") == "order" else r["scenario"]
        groups.setdefault(key, []).append(r)
    by_order = summary.get("by") == "order"
    # variants carry sentences for names: they read down the side, values across
    tall = max(len(m) for m in groups.values())
    size = (5 * len(groups), 3.6) if by_order else (9 * len(groups), 1.2 + 0.4 * tall)
    fig, axes = plt.subplots(1, len(groups), figsize=size, squeeze=False)
    colour = as_matplotlib(method_colour(0))  # the studies' one method, C2INet-online
    for ax, (key, members) in zip(axes[0], groups.items(), strict=True):
        names = [m["scenario"] if by_order else m["variant"] for m in members]
        names = [n.replace("eth_ucy_", "").replace("crowd_radius_", "r ") for n in names]
        at = list(range(len(members)))
        for metric, style in (("avg_seen_ade", "-o"), ("avg_seen_fde", "--s")):
            values = [m[metric][-1] for m in members]
            errors = [m[f"{metric}_std"][-1] for m in members]
            x, y, spread = (at, values, "yerr") if by_order else (values, at, "xerr")
            fmt = style if by_order else style[-1]  # variants: markers, no line between rows
            ax.errorbar(
                x,
                y,
                **{spread: errors},
                fmt=fmt,
                capsize=3,
                label=metric[-3:].upper(),
                color=colour,
            )
        if by_order:
            ax.set_xticks(at, names, rotation=20, ha="right", fontsize=8)
            ax.set_ylabel("final average over tasks (m)")
        else:
            ax.set_yticks(at, names, fontsize=8)
            ax.invert_yaxis()  # the full model first, as in the table
            ax.set_xlabel("final average over tasks (m), mean ± std over seeds")
        ax.set_title(key, fontsize=9)
        ax.legend(fontsize=8)
    fig.suptitle(summary["study"], fontsize=10)
    fig.tight_layout()
    save_figure(fig, path)


def leaderboard_figure(board: dict[str, Any], path: Path) -> None:
    """The benchmark's ranking: final average ADE and final forgetting on the metric the board
    ranks (the point prediction, or best of K), each a point with its 95 % interval, one row per
    method in rank order (* p < alpha)."""
    metric = board.get("metric", "ade_k1")  # a board written before it said: the point
    what = "K = 1" if metric == "ade_k1" else f"best of {board['k']}"
    entries = board["entries"]
    names = [e["method"] for e in entries]
    rows = np.arange(len(entries))
    bases = sorted({name.split(",")[0] for name in names})  # a method's test rules share its colour
    reference = next((e for e in entries if e["method"] == board["reference"]), None)
    fig, axes = plt.subplots(1, 2, figsize=(11, 0.35 * len(entries) + 1.6), sharey=True)
    for ax, key, title in (
        (axes[0], f"final_{metric}", f"final average ADE, {what} (m)"),
        (axes[1], f"forgetting_final_{metric}", f"final forgetting, {what} (m)"),
    ):
        for row, e in zip(rows, entries, strict=True):
            mean, bounds = e[key]["mean"], e[key]["interval"] or [e[key]["mean"]] * 2
            colour = as_matplotlib(method_colour(bases.index(e["method"].split(",")[0])))
            ax.errorbar(
                mean,
                row,
                xerr=[[mean - bounds[0]], [bounds[1] - mean]],
                fmt="o",
                color=colour,
                capsize=3,
            )
            if key == f"final_{metric}" and e[key]["significant"]:
                ax.annotate("*", (bounds[1], row), xytext=(4, -4), textcoords="offset points")
        ax.set_xlabel(title)
        ax.grid(axis="x", color="0.9")
        if reference is not None:  # the line every paired test compares with
            ax.axvline(reference[key]["mean"], color="0.5", lw=0.8, ls="--")
    axes[1].axvline(0, color="0.7", lw=0.8)
    axes[0].set_yticks(rows, names)
    axes[0].invert_yaxis()
    if board.get("tuned_from"):  # evaluated from a tuning made elsewhere: no trial ran here
        tuning = f"settings from {Path(board['tuned_from']['file']).name}"
    elif board.get("design"):
        tuning = "tuned by the staged design"
    else:
        tuning = f"{board['trials']} trials a method"
    fig.suptitle(
        f"{board['scenario']}: {tuning}, {board['seeds']} seeds "
        f"(bars: 95 % intervals of the mean; * p < {board['alpha']} in a paired test against "
        f"{board['reference']}{', Holm-adjusted' if board.get('correction') else ''})",
        fontsize=9,
    )
    fig.tight_layout()
    save_figure(fig, path)


def calibration_figure(report: dict[str, Any], path: Path) -> None:
    """Left: the objective of every trial and the best so far; right: each profile's scaled
    distance to the reference before and after the fit."""
    fig, (left, right) = plt.subplots(1, 2, figsize=(10, 3.6))
    history = [v if v < 1e8 else np.nan for v in report["history"]]
    left.plot(range(1, len(history) + 1), history, "o", ms=3, color="0.6", label="trial")
    left.plot(range(1, len(history) + 1), np.fmin.accumulate(history), color="C0", label="best")
    left.set_xlabel("trial")
    left.set_ylabel("objective (mean scaled W1)")
    left.legend(frameon=False)
    names = list(report["after"]["distances"]) or list(report["before"]["distances"])
    x = np.arange(len(names))
    for offset, side, colour in ((-0.2, "before", "0.6"), (0.2, "after", "C0")):
        values = [report[side]["distances"].get(n) or np.nan for n in names]
        right.bar(x + offset, values, 0.4, color=colour, label=side)
    right.set_xticks(x, names, fontsize=8)
    right.set_ylabel("W1 / reference spread")
    right.legend(frameon=False)
    fig.suptitle(f"{report['family']} calibrated to {report['reference']}", fontsize=10)
    save_figure(fig, path)


def reproduce_figure(report: dict[str, Any], path: Path) -> None:
    """Best-of-K ADE per scene (the minimum per scene, sgan's windows): each measured method
    beside the published rows of that protocol."""
    scenes = [s.upper() for s in report["scenes"]]
    bars = {
        name: [ade for ade, _ in published["rows"]]
        for name, published in report["published"].items()
        if published["minimum"] == "scene"
    }
    for method, windows in report["measured"].items():
        bars[f"{method} (here)"] = [ade for ade, _ in windows["sgan"]["scene"]]
    fig, ax = plt.subplots(figsize=(8, 3.6))
    width = 0.8 / len(bars)
    for i, (name, values) in enumerate(bars.items()):
        x = np.arange(len(scenes)) + (i - (len(bars) - 1) / 2) * width
        ax.bar(x, values, width, label=name, color=as_matplotlib(method_colour(i)))
    ax.set_xticks(np.arange(len(scenes)), scenes)
    ax.set_ylabel(f"ADE, best of {report['k']} (m)")
    ax.set_title("ETH-UCY leave one scene out: the minimum per scene", fontsize=9)
    ax.legend(fontsize=7, ncol=2)
    fig.tight_layout()
    save_figure(fig, path)
