"""What a run leaves behind, and the folder it goes in.

A run's folder holds ``config.json`` (what it computes and how, written first), ``jobs/`` (per
method and seed: checkpoints, ``result.json``, the job's recording), and when it finishes
``metrics.json`` (the machine-readable contract: per method best-of-K joint ``ade``/``fde``,
the point prediction's ``ade_k1``/``fde_k1``, one random draw's ``ade_draw``/``fde_draw``,
``avg_seen_ade``, ``forgetting_final_ade`` and ``forgetting_worst_ade``, ``diagnostics``,
``seeds``; row i is after task i), ``matrices/*.csv``,
``report.md``, ``figures/``, ``run_card.json`` and ``recording.rrd``. The folder itself, and
what may be removed from it, is ``sim.experiment.folders``'s.
"""

from __future__ import annotations

import itertools
import json
import platform
import shlex
import subprocess
import time
from dataclasses import asdict
from importlib import metadata
from pathlib import Path
from typing import TYPE_CHECKING, Any

import pyarrow as pa
import pyarrow.parquet as pq
import torch

from c2inet.device import resolve_device
from c2inet.files import (
    file_digest,
    writable_folder,
    write_atomic,
    write_text_atomic,
)
from c2inet.report import compare, matrix_csv, summarise, summarise_diagnostics
from c2inet.report_markdown import markdown_report
from sim.data import SPLITS
from sim.experiment.folders import MARKER, TRUTH_PART, record_written
from viz.cli import config_path
from viz.loggers import log_outputs
from viz.recording import merge_recordings

if TYPE_CHECKING:
    from sim.experiment.config import Execution, ExperimentConfig
    from sim.experiment.curriculum import Curriculum
    from sim.experiment.jobs import JobResult


def config_file(argv: list[str]) -> dict[str, str] | None:
    """The ``--config`` file of a command line, with its SHA-256 (None without one); its options
    are in the run card already, as the configuration they gave."""
    path = config_path(argv)
    if path is None:
        return None
    return {"path": str(path.resolve()), "sha256": file_digest(path) if path.is_file() else None}


def versions() -> dict[str, str]:
    out = {"python": platform.python_version()}
    for package in ("torch", "numpy", "pymunk", "rerun-sdk", "highway-env", "ray", "c2i-testbed"):
        try:
            out[package] = metadata.version(package)
        except metadata.PackageNotFoundError:
            out[package] = "missing"
    return out


def git_commit() -> str | None:
    """The checkout's commit (``+dirty`` with uncommitted changes), None outside a git checkout."""
    here = Path(__file__).parent

    def git(*args: str) -> str:
        done = subprocess.run(
            ["git", "-C", str(here), *args], capture_output=True, text=True, check=True
        )
        return done.stdout.strip()

    try:
        commit = git("rev-parse", "HEAD")
        return commit + ("+dirty" if git("status", "--porcelain", "--untracked-files=no") else "")
    except (OSError, subprocess.CalledProcessError):
        return None


def summarise_jobs(config: ExperimentConfig, results: list[JobResult]) -> dict[str, dict]:
    """Per method: mean and std over seeds of every matrix and summary, the first seed's
    history, and the diagnostics averaged over seeds."""
    out: dict[str, dict] = {}
    for name in config.methods:
        runs = [r.result for r in results if r.job.method == name]
        out[name] = summarise([r.matrices for r in runs], [r.summaries for r in runs])
        out[name]["history"] = runs[0].history
        out[name]["diagnostics"] = summarise_diagnostics([r.diagnostics for r in runs])
    return out


COLUMNS = ("scenario", "method", "seed", "setting", "after_task", "on_task", "metric", "value")
COLUMNS += ("quick",)  # tiny smoke-test sizes: never to be read as a result


def tidy_rows(label: str, config: ExperimentConfig, results: list[JobResult]) -> dict[str, list]:
    """Every matrix cell of every job, one row each."""
    rows: dict[str, list] = {c: [] for c in COLUMNS}
    for done in results:
        tasks = done.result.tasks
        cell = (config.scenario, done.job.method, config.seed + done.job.seed_index)
        for metric, matrix in done.result.matrices.items():
            for (i, after), (j, on) in itertools.product(enumerate(tasks), enumerate(tasks)):
                values = (*cell, label, after, on, metric, float(matrix[i, j]), config.quick)
                for column, value in zip(COLUMNS, values, strict=True):
                    rows[column].append(value)
    return rows


def write_results(path: Path, rows: dict[str, list]) -> None:
    """``results.parquet``: tidy rows (``COLUMNS``), one per matrix cell of every job."""
    table = pa.table(rows)
    write_atomic(path, lambda tmp: pq.write_table(table, tmp))


def write_outputs(
    out: Path,
    config: ExperimentConfig,
    execution: Execution,
    curriculum: Curriculum,
    results: list[JobResult],
    truth,
    wall: float,
    argv: list[str],
    label: str = "default",
    figures: bool = True,
) -> dict[str, Any]:
    """metrics.json, matrices, run card, report, figures (unless not ``figures``) and the merged
    recording; returns the metrics. ``truth``: the run's own recorder (None when nothing is
    recorded)."""
    tasks = [t.name for t in curriculum.inputs.tasks]
    summary = summarise_jobs(config, results)
    metrics = {
        "scenario": config.scenario,
        "tasks": tasks,
        "labels": curriculum.labels,
        "k": config.k,
        "seed": config.seed,
        "epochs": config.epochs,
        "unit": config.unit,
        "methods": summary,
        "comparison": compare(summary),
    }
    write_text_atomic(out / "metrics.json", json.dumps(metrics, indent=1) + "\n")
    write_results(out / "results.parquet", tidy_rows(label, config, results))
    for name, result in summary.items():
        first = next(r.result for r in results if r.job.method == name)
        for key in first.matrices:
            write_text_atomic(
                out / "matrices" / f"{name}_{key}.csv", matrix_csv(result[key], tasks)
            )
    card = json.dumps(run_card(config, execution, curriculum, wall, argv), indent=1)
    write_text_atomic(out / "run_card.json", card + "\n")
    run, report = write_report_and_figures(
        out, config, curriculum, summary, results, wall, argv, figures
    )
    if truth is not None:
        truth.log_run_card(f"{report}\n## Run card\n\n```json\n{card}\n```\n")
        truth.close()
        if config.record:
            parts = [out / TRUTH_PART]
            parts += [r.job.folder(out) / "recording.rrd" for r in results if r.predictions]
            merge_recordings(parts, out / "recording.rrd")
            parts[0].unlink()
    if execution.loggers:  # the trackers that keep files get the report, figures and recording
        shown = ["report.md", "metrics.json", "recording.rrd", *run["figures"]]
        files = [out / name for name in shown if (out / name).is_file()]
        log_outputs(execution.loggers, out, execution.tracking or out, files)
    return metrics


def write_report_and_figures(
    out: Path,
    config: ExperimentConfig,
    curriculum: Curriculum,
    summary: dict[str, Any],
    results: list[JobResult],
    wall: float,
    argv: list[str],
    figures: bool,
) -> tuple[dict[str, Any], str]:
    """``figures/`` (unless not ``figures``) and ``report.md``, which links them, gives the
    command and marks quick sizes; returns what the report says of the run, and the report."""
    run = {
        "quick": config.quick,
        "size": config.size,
        "epochs": config.epochs,
        "seeds": config.seeds,
        "wall_seconds": wall,
        "command": shlex.join(argv),
        "recording": "recording.rrd" if config.record else None,
        "unit": config.unit,
        "figures": [],
        "network": f"{config.backbone}, {config.kernels_used()} kernels",
    }
    if figures:
        note = "quick sizes: a smoke test, not a result" if config.quick else None
        draw_figures(out, curriculum, summary, results, note, config.unit)
        run["figures"] = sorted(p.relative_to(out).as_posix() for p in out.glob("figures/*.png"))
    report = markdown_report(config.scenario, curriculum.labels, config.k, summary, run)
    write_text_atomic(out / "report.md", report)
    return run, report


def run_card(config, execution, curriculum, wall: float, argv: list[str]) -> dict[str, Any]:
    """How a run ran: its command, commit, machine, sizes, options and versions."""
    return {
        "scenario": config.scenario,
        "seed": config.seed,
        "seeds": config.seeds,
        "methods": list(config.methods),
        "quick": config.quick,
        "size": config.size,
        "command": shlex.join(argv),
        "git_commit": git_commit(),
        "finished": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
        "host": platform.node(),
        "backend": execution.backend,
        "jobs": execution.jobs,
        "threads": torch.get_num_threads(),  # what torch uses, not only what was asked
        "device_used": str(resolve_device(config.device)),  # "auto" resolved on this machine
        "kernels": config.kernels_used(),
        "wall_seconds": round(wall, 1),
        "model": asdict(config.model_config()),
        "train": asdict(config.train_config()),
        "settings": config.settings,
        "versions": versions(),
        "domains": [d.summary() for d in curriculum.domains],
        "windows": {t.name: _window_counts(t) for t in curriculum.inputs.tasks},
        "config_file": config_file(argv),
    }


def draw_figures(
    out: Path,
    curriculum: Curriculum,
    summary: dict,
    results: list[JobResult],
    note: str | None = None,
    unit: str = "m",
):
    """A run's figures: every method's error matrix and per-task ADE, the average over seen
    tasks, and the sample predictions, in ``unit``; each carries ``note`` (quick sizes)."""
    from viz import figures  # matplotlib: imported by the run that draws, not by every command

    with figures.labelled(note, unit):
        _draw_figures(figures, out, curriculum, summary, results)


def _draw_figures(figures, out: Path, curriculum: Curriculum, summary: dict, results) -> None:
    labels = curriculum.labels
    families = [s.family.name for s in curriculum.specs]
    for name, result in summary.items():
        matrix = out / "figures" / f"matrix_{name}.png"
        figures.error_matrix(name, result["ade"], labels, matrix, families)
        figures.per_task(name, result["ade"], labels, out / "figures" / f"per_task_{name}.png")
    figures.average_seen(summary, labels, out / "figures" / "average_seen.png")
    drawn = {r.job.method: r.predictions for r in results if r.predictions}
    if drawn:
        samples = {show.task: show.scenes for show in curriculum.inputs.showcases}
        figures.prediction_grid(samples, drawn, out / "figures" / "predictions.png")


def _window_counts(task) -> dict[str, int]:
    """Windows per split of a task (0 for a missing split)."""
    return {s: 0 if getattr(task, s) is None else len(getattr(task, s)) for s in SPLITS}


def write_report(out: Path, name: str, report: dict[str, Any], markdown, figure) -> None:
    """A study's three files in ``out``: ``NAME.json`` (``report``), ``NAME.md``
    (``markdown(report)``) and ``NAME.png`` (``figure(report, path)``), each written whole."""
    writable_folder(out, "--out")
    if (out / MARKER).is_file():  # a folder of ours: its marker learns the report's names
        record_written(out, [f"{name}.{ext}" for ext in ("json", "md", "png")])
    write_text_atomic(out / f"{name}.json", json.dumps(report, indent=1) + "\n")
    write_text_atomic(out / f"{name}.md", markdown(report))
    figure(report, out / f"{name}.png")
