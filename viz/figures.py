"""The paper's figures as PNGs: error matrices, per-task ADE, averages over seen tasks, samples."""

from __future__ import annotations

from contextlib import contextmanager
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.lines import Line2D  # noqa: E402

from c2inet.data import Windows  # noqa: E402
from c2inet.files import write_atomic  # noqa: E402
from viz.colours import FUTURE, OBSERVED, as_matplotlib, method_colour  # noqa: E402

_NOTES: list[tuple[str | None, str]] = []  # (note, unit) of the figures drawn inside labelled()


@contextmanager
def labelled(note: str | None = None, unit: str = "m"):
    """Figures saved inside carry ``note`` (e.g. that the sizes were quick) across their middle,
    so a figure passed on alone still says what it is, and give errors and scale bars in
    ``unit`` (m, or px for a recording not yet scaled)."""
    _NOTES.append((note, unit))
    try:
        yield
    finally:
        _NOTES.pop()


def figure_unit() -> str:
    """The unit of the figures being drawn (``labelled``'s; metres outside it)."""
    return _NOTES[-1][1] if _NOTES else "m"


def save_figure(fig, path: Path) -> Path:
    """Write ``fig`` to ``path`` (atomically) with the note of ``labelled``, and close it."""
    if _NOTES and _NOTES[-1][0]:
        fig.text(
            0.5,
            0.5,
            _NOTES[-1][0],
            ha="center",
            va="center",
            fontsize=18,
            color="red",
            alpha=0.35,
            rotation=20,
            transform=fig.transFigure,
        )
    write_atomic(path, lambda tmp: fig.savefig(tmp, format="png", dpi=110, bbox_inches="tight"))
    plt.close(fig)
    return path


def error_matrix(
    name: str,
    matrix: list[list[float]],
    labels: list[str],
    path: Path,
    families: list[str] | None = None,
) -> Path:
    """Heat map of ``R[i][j]``: ADE on task j after training through task i.

    With tasks of several ``families`` (one per column), each family's columns get a colour
    scale of their own, so metres of traffic error do not wash out metres of crowd error.
    """
    data = np.array(matrix, dtype=float)
    fig, ax = plt.subplots(figsize=(1.1 * len(labels) + 2, 0.9 * len(labels) + 1.5))
    mixed = families is not None and len(set(families)) > 1
    shade = data.copy()
    for family in set(families) if mixed else ():
        columns = [j for j, f in enumerate(families) if f == family]
        block = data[:, columns]
        low, high = np.nanmin(block), np.nanmax(block)
        shade[:, columns] = (block - low) / (high - low) if high > low else 0.5
    image = ax.imshow(shade, cmap="viridis")
    for i in range(len(labels)):
        for j in range(len(labels)):
            light = image.norm(shade[i, j]) > 0.6  # dark text on the light end of viridis
            colour = "black" if light else "white"
            ax.text(j, i, f"{data[i, j]:.2f}", ha="center", va="center", color=colour, fontsize=8)
    ax.set_xticks(range(len(labels)), labels, rotation=45)
    ax.set_yticks(range(len(labels)), labels)
    ax.set_xlabel("evaluated on task")
    ax.set_ylabel("after training through task")
    if mixed:
        ax.set_title(f"{name}: ADE ({figure_unit()}); colour scaled per family, low to high")
    else:
        ax.set_title(f"{name}: ADE ({figure_unit()})")
        fig.colorbar(image, ax=ax, label=f"ADE ({figure_unit()})")
    return save_figure(fig, path)


def per_task(name: str, matrix: list[list[float]], labels: list[str], path: Path) -> Path:
    """ADE on every task as training proceeds (the paper's Figs 5 and 6)."""
    data = np.array(matrix, dtype=float)
    fig, ax = plt.subplots(figsize=(6, 4))
    for j, label in enumerate(labels):
        ax.plot(range(j, len(labels)), data[j:, j], marker="o", label=label)
    ax.set_xticks(range(len(labels)), labels)
    ax.set_xlabel("after training through task")
    ax.set_ylabel(f"ADE ({figure_unit()})")
    ax.set_title(f"{name}: per-task ADE")
    ax.legend(fontsize=7, title="task")
    return save_figure(fig, path)


def average_seen(methods: dict[str, dict[str, Any]], labels: list[str], path: Path) -> Path:
    """ADE averaged over the tasks seen so far, every method on one plot (Table 2 as curves),
    in the methods' colours, with a band of one std over seeds."""
    fig, ax = plt.subplots(figsize=(6, 4))
    for index, (name, m) in enumerate(methods.items()):
        mean, std = np.array(m["avg_seen_ade"]), np.array(m.get("avg_seen_ade_std", 0.0))
        colour = as_matplotlib(method_colour(index))
        ax.plot(range(len(mean)), mean, marker="o", label=name, color=colour)
        ax.fill_between(range(len(mean)), mean - std, mean + std, alpha=0.15, color=colour)
    ax.set_xticks(range(len(labels)), [labels[0], *(":" + lab for lab in labels[1:])])
    ax.set_xlabel("after training through task (:x = averaged over the tasks up to x)")
    ax.set_ylabel(f"average ADE over seen tasks ({figure_unit()})")
    ax.legend(fontsize=8)
    return save_figure(fig, path)


def prediction_grid(
    samples: dict[str, Windows], predictions: dict[str, dict[str, np.ndarray]], path: Path
) -> Path:
    """Rows: methods; columns: tasks; the first sample scene of each (the paper's Fig 8).

    Grey: observed, green: truth, the method's colour: its K predicted samples. A bar in each
    panel gives the scale; the legend says what the colours are.
    """
    methods, tasks = list(predictions), list(samples)
    fig, axes = plt.subplots(
        len(methods),
        len(tasks),
        figsize=(2.6 * len(tasks), 2.6 * len(methods) + 0.6),
        squeeze=False,
    )
    observed, future = as_matplotlib(OBSERVED), as_matplotlib(FUTURE)
    for r, method in enumerate(methods):
        colour = as_matplotlib(method_colour(r))
        for c, task in enumerate(tasks):
            ax, windows = axes[r, c], samples[task]
            agents = slice(0, windows.scene_start[1])
            pos, obs = windows.positions[agents], windows.obs_len
            pred = predictions[method][task][:, agents]
            for a in range(pos.shape[0]):
                for k in range(pred.shape[0]):
                    path_k = np.vstack([pos[a, obs - 1], pred[k, a]])
                    ax.plot(path_k[:, 0], path_k[:, 1], color=colour, alpha=0.3, lw=0.8)
                ax.plot(pos[a, :obs, 0], pos[a, :obs, 1], color=observed, lw=1.5)
                ax.plot(pos[a, obs - 1 :, 0], pos[a, obs - 1 :, 1], color=future, lw=1.5)
            ax.set_aspect("equal")
            ax.set_xticks([])
            ax.set_yticks([])
            _scale_bar(ax)
            if r == 0:
                ax.set_title(task, fontsize=8)
            if c == 0:
                ax.set_ylabel(method, fontsize=8)
    handles = [
        Line2D([], [], color=observed, lw=1.5, label="observed"),
        Line2D([], [], color=future, lw=1.5, label="true future"),
        *(
            Line2D([], [], color=as_matplotlib(method_colour(i)), lw=1.5, label=m)
            for i, m in enumerate(methods)
        ),
    ]
    fig.legend(handles=handles, loc="lower center", ncol=len(handles), fontsize=8, frameon=False)
    fig.subplots_adjust(bottom=0.6 / fig.get_figheight())
    return save_figure(fig, path)


def _scale_bar(ax) -> None:
    """A bar of a round length (1, 2 or 5 times a power of ten, in the figures' unit) near a
    fifth of the panel's width, in its lower left corner."""
    (x0, x1), (y0, y1) = ax.get_xlim(), ax.get_ylim()
    span = x1 - x0
    power = 10.0 ** np.floor(np.log10(max(span / 5, 1e-9)))
    length = next(f * power for f in (1, 2, 5, 10) if f * power >= span / 5)
    x, y = x0 + 0.05 * span, y0 + 0.06 * (y1 - y0)
    ax.plot([x, x + length], [y, y], color="black", lw=2)
    ax.text(
        x + length / 2, y + 0.02 * (y1 - y0), f"{length:g} {figure_unit()}", ha="center", fontsize=7
    )


# The studies' figures (sim.studies): each takes the study's report.
