"""What a run leaves behind, and the folder it goes in.

A run's folder holds ``config.json`` (what it computes and how, written first), ``jobs/`` (per
method and seed: checkpoints, ``result.json``, the job's recording), and when it finishes
``metrics.json`` (the machine-readable contract: per method best-of-K joint ``ade``/``fde``,
the point prediction's ``ade_k1``/``fde_k1``, one random draw's ``ade_draw``/``fde_draw``,
``avg_seen_ade``, ``forgetting_final_ade`` and ``forgetting_worst_ade``, ``diagnostics``,
``seeds``; row i is after task i), ``matrices/*.csv``,
``report.md``, ``figures/``, ``run_card.json`` and ``recording.rrd``. Folders never mix runs.
"""

from __future__ import annotations

import fcntl
import hashlib
import itertools
import json
import os
import platform
import re
import shlex
import shutil
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
from c2inet.errors import InputError
from c2inet.files import (
    TEMPORARY_SUFFIX,
    file_digest,
    writable_folder,
    write_atomic,
    write_text_atomic,
)
from c2inet.report import (
    compare,
    markdown_report,
    matrix_csv,
    summarise,
    summarise_diagnostics,
)
from sim.data import SPLITS
from viz.cli import config_path
from viz.recording import merge_recordings

if TYPE_CHECKING:
    from sim.experiment.config import Execution, ExperimentConfig
    from sim.experiment.curriculum import Curriculum
    from sim.experiment.jobs import JobResult

RUNS = Path("runs")
TRUTH_PART = "truth.partial.rrd"  # the run's own recording until it is merged with the jobs'
MARKER = ".c2i-run"  # written first into every run folder: the proof that the folder is ours
LOCK = ".c2i-run.lock"  # held (an OS file lock) by the process that runs or resumes the folder
_LOCKS: dict[Path, int] = {}  # the folders this process holds, and the lock files' descriptors
# the studies' NAME.json/.md/.png, and the benchmark's board
RUN_FILES = {
    MARKER,
    LOCK,
    "config.json",
    "metrics.json",
    "run_card.json",
    "report.md",
    "results.parquet",
    "recording.rrd",
    "recording.partial.rrd",
    TRUTH_PART,
    "summary.json",
    "spent.json",  # a benchmark's time
    "tuning.db",  # a tuning's Optuna studies (in its own marked folder)
    "tuning.json",
}
RUN_FOLDERS = {"jobs", "matrices", "figures", "logs", "tensorboard", "cache", "cells"}
MAX_CONFIG_BYTES = 1 << 20  # a run's config.json is a few kilobytes
TEMPORARY = re.compile(r"^\.[^/]+\.[A-Za-z0-9_]{8}" + re.escape(TEMPORARY_SUFFIX) + "$")


MAX_NAME = 100  # characters of a folder named after a scenario or a setting


def run_root(scenario: str) -> Path:
    """``runs/<scenario>`` with every character outside [A-Za-z0-9._,+-] replaced by '_'; a
    name longer than ``MAX_NAME`` keeps its start and ends in a hash of the whole."""
    name = re.sub(r"[^A-Za-z0-9._,+-]", "_", scenario).strip(".") or "scenario"
    if len(name) > MAX_NAME:
        digest = hashlib.sha256(scenario.encode()).hexdigest()[:12]
        name = f"{name[: MAX_NAME - 13]}-{digest}"
    return RUNS / name


def output_folder(scenario: str, out: Path | None, resume: bool = False) -> Path:
    """The run's folder: ``out``, or without it a fresh ``runs/<scenario>/<timestamp>`` with a
    ``latest`` link beside it (with ``resume``: the folder ``latest`` points to)."""
    if out is not None:
        return out
    root = run_root(scenario)
    latest = root / "latest"
    if resume:
        if not latest.exists():
            raise InputError(f"--resume: no earlier run of {scenario} under {root}; give --out")
        return root / os.readlink(latest)
    stamp = time.strftime("%Y%m%d-%H%M%S")
    for attempt in range(1, 100):
        name = stamp if attempt == 1 else f"{stamp}-{attempt}"
        try:
            (root / name).mkdir(parents=True)
            break
        except FileExistsError:
            continue
    link = root / f".latest.{os.getpid()}"
    link.unlink(missing_ok=True)
    link.symlink_to(name)
    os.replace(link, latest)
    return root / name


def claim(
    out: Path,
    config: ExperimentConfig,
    execution: Execution,
    resume: bool = False,
    overwrite: bool = False,
) -> None:
    """Make ``out`` this run's: refuse a folder holding something else, check that a resumed run
    has the same configuration, and write ``config.json``."""
    saved = out / "config.json"
    if resume and not saved.is_file():
        raise InputError(f"--resume: {out} holds no run to resume (no config.json)")
    ours = (out / MARKER).is_file() or resume  # a resumable run of an earlier version counts
    if not ours and out.is_dir() and _holds_files(out):  # refused before anything is written
        if overwrite:
            raise InputError(
                f"--overwrite: {out} holds no run of this project (no {MARKER}), so it is not "
                "removed; remove it yourself or choose another --out"
            )
        raise InputError(
            f"--out {out}: not empty; add --resume to continue the run in it, "
            "or --overwrite to replace it"
        )
    held = out.resolve() in _LOCKS
    lock_run(out)
    try:
        _claim_locked(out, config, execution, resume, overwrite)
    except InputError:  # refused: another process may claim the folder now (not a later call)
        if not held:
            unlock_run(out)
        raise


def _claim_locked(
    out: Path, config: ExperimentConfig, execution: Execution, resume: bool, overwrite: bool
) -> None:
    """The part of :func:`claim` done under the folder's lock."""
    saved = out / "config.json"
    if resume:
        before = saved_experiment(saved)
        now = json.loads(json.dumps(config.to_json()))
        changed = sorted(k for k in now if before.get(k) != now[k])
        if changed:
            raise InputError(
                f"--resume: {out} holds a run with other {', '.join(changed)}; "
                "resume it with the same options, or use --overwrite"
            )
        if not (out / MARKER).is_file():  # a run of an earlier version: the same configuration
            mark_run(out)
        remove_leftovers(out)
        return
    if _holds_files(out):
        if not overwrite:
            raise InputError(
                f"--out {out}: not empty; add --resume to continue the run in it, "
                "or --overwrite to replace it"
            )
        remove_run(out)
    mark_run(out)
    data = {"experiment": config.to_json(), "execution": _plain(asdict(execution))}
    write_text_atomic(saved, json.dumps(data, indent=1) + "\n")


def saved_experiment(saved: Path) -> dict[str, Any]:
    """The ``experiment`` table of a run's ``config.json``; a damaged file is one clear error."""
    try:
        if saved.stat().st_size > MAX_CONFIG_BYTES:
            raise ValueError(f"larger than {MAX_CONFIG_BYTES} bytes")
        experiment = json.loads(saved.read_text())["experiment"]
        if not isinstance(experiment, dict):
            raise TypeError("its experiment is not a table")
    except (OSError, UnicodeDecodeError, ValueError, KeyError, TypeError, RecursionError) as error:
        why = f"no {error}" if isinstance(error, KeyError) else str(error).splitlines()[0]
        raise InputError(
            f"--resume: {saved} is damaged ({why}); it cannot say what the run was, so nothing "
            "is resumed: use --overwrite to start the run again"
        ) from None
    return experiment


def _holds_files(out: Path) -> bool:
    return any(p.name != LOCK for p in out.iterdir())


def lock_run(out: Path) -> None:
    """Hold the folder's lock for as long as this process lives (the OS releases it when the
    process ends, however it ends); a second run or resume of the folder gets one line."""
    key = out.resolve()
    if key in _LOCKS:
        return
    writable_folder(out, "--out")
    fd = os.open(out / LOCK, os.O_RDWR | os.O_CREAT, 0o644)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        os.close(fd)
        raise InputError(
            f"--out {out}: another run or resume is using this folder; wait for it to end, "
            "or choose another --out"
        ) from None
    _LOCKS[key] = fd


def unlock_run(out: Path) -> None:
    """Release the folder's lock this process holds (a refused claim)."""
    fd = _LOCKS.pop(out.resolve(), None)
    if fd is not None:
        os.close(fd)  # closing the descriptor releases its flock


MARKER_TEXT = "a run folder of c2i-testbed: --overwrite may remove it"


def mark_run(out: Path) -> None:
    """Write the run marker, before anything else of the run."""
    write_text_atomic(out / MARKER, MARKER_TEXT + "\n")


def record_written(out: Path, names: list[str]) -> None:
    """Add ``names`` (files of ``out`` beyond every run's own, e.g. a study's report) to the
    marker, before they are written: ``--overwrite`` then knows them for ours, and nothing else."""
    written = sorted(set(marked_files(out)) | set(names))
    text = MARKER_TEXT + "\n" + "".join(f"wrote: {name}\n" for name in written)
    write_text_atomic(out / MARKER, text)


def marked_files(out: Path) -> list[str]:
    """The file names the marker of ``out`` records as written (plain names, nothing else)."""
    try:
        lines = (out / MARKER).read_text(encoding="utf-8").splitlines()
    except (OSError, UnicodeDecodeError):
        return []
    names = [line.removeprefix("wrote: ") for line in lines if line.startswith("wrote: ")]
    return [n for n in names if n and "/" not in n and n not in (".", "..")]


def config_file(argv: list[str]) -> dict[str, str] | None:
    """The ``--config`` file of a command line, with its SHA-256 (None without one); its options
    are in the run card already, as the configuration they gave."""
    path = config_path(argv)
    if path is None:
        return None
    return {"path": str(path.resolve()), "sha256": file_digest(path) if path.is_file() else None}


def remove_leftovers(out: Path) -> list[Path]:
    """Remove the temporary files that interrupted atomic writes left in a run folder of ours
    (``.NAME.XXXXXXXX.c2i-tmp``: never a user's ``.notes.20241201``); returns them."""
    leftovers = [p for p in out.rglob(".*") if p.is_file() and TEMPORARY.match(p.name)]
    for path in leftovers:
        path.unlink()
    return leftovers


def _run_output(entry: Path) -> bool:
    """A file or folder a run writes into its own folder (or that its marker records)."""
    if entry.is_file():
        ours = entry.name in RUN_FILES or entry.name in marked_files(entry.parent)
        return ours or bool(TEMPORARY.match(entry.name))
    return entry.is_dir() and entry.name in RUN_FOLDERS


def foreign_entry(folder: Path, runs_only: bool = False) -> Path | None:
    """The first entry of ``folder`` that a run of ours does not write (None: all ours).

    Ours: the marker and the run's own files and folders, temporary files of an interrupted
    write, and nested run folders (a sweep's, a tuning's trials), alone or grouped in plain
    folders, at any depth, that hold nothing else (``runs_only``)."""
    for entry in sorted(folder.iterdir()):
        run = entry.is_dir() and not entry.is_symlink() and (entry / MARKER).is_file()
        if entry.is_symlink():
            return entry
        if run:
            inner = foreign_entry(entry)
        elif runs_only:
            grouped = entry.is_dir() and any(entry.iterdir())
            inner = foreign_entry(entry, runs_only=True) if grouped else entry
        elif _run_output(entry):
            continue
        elif entry.is_dir() and any(entry.iterdir()):  # a sweep's scenario folder
            inner = foreign_entry(entry, runs_only=True)
        else:
            inner = entry
        if inner is not None:
            return inner
    return None


def remove_run(out: Path) -> None:
    """Remove a run folder for ``--overwrite``, only if it is provably a run of ours: it holds
    the marker and nothing a run does not write; never the current folder, one above it, the
    home folder or the filesystem's root."""
    folder = out.resolve()
    protected = {Path.home().resolve(), Path(folder.anchor)}
    if folder in protected or Path.cwd().resolve().is_relative_to(folder):
        raise InputError(f"--overwrite: {out} is not a run folder, so it is not removed")
    if not (folder / MARKER).is_file():
        raise InputError(f"--overwrite: {out} holds no run of this project (no {MARKER})")
    foreign = foreign_entry(folder)
    if foreign is not None:
        raise InputError(
            f"--overwrite: {out} holds {foreign.relative_to(folder)}, which no run writes, so "
            "it is not removed; move it away or choose another --out"
        )
    for entry in folder.iterdir():  # all but the lock this process holds
        if entry.is_dir():
            shutil.rmtree(entry)
        elif entry.name != LOCK:
            entry.unlink()


def _plain(values: dict[str, Any]) -> dict[str, Any]:
    return {k: str(v) if isinstance(v, Path) else v for k, v in values.items()}


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
    labels = curriculum.labels
    summary = summarise_jobs(config, results)
    metrics = {
        "scenario": config.scenario,
        "tasks": tasks,
        "labels": labels,
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
    run_card = {
        "scenario": config.scenario,
        "seed": config.seed,
        "seeds": config.seeds,
        "methods": list(config.methods),
        "quick": config.quick,
        "command": shlex.join(argv),
        "git_commit": git_commit(),
        "finished": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
        "host": platform.node(),
        "backend": execution.backend,
        "jobs": execution.jobs,
        "threads": torch.get_num_threads(),  # what torch uses, not only what was asked
        "device_used": str(resolve_device(config.device)),  # "auto" resolved on this machine
        "wall_seconds": round(wall, 1),
        "model": asdict(config.model_config()),
        "train": asdict(config.train_config()),
        "settings": config.settings,
        "versions": versions(),
        "domains": [d.summary() for d in curriculum.domains],
        "windows": {t.name: _window_counts(t) for t in curriculum.inputs.tasks},
        "config_file": config_file(argv),
    }
    card = json.dumps(run_card, indent=1)
    write_text_atomic(out / "run_card.json", card + "\n")
    run = {
        "quick": config.quick,
        "epochs": config.epochs,
        "seeds": config.seeds,
        "wall_seconds": wall,
        "command": shlex.join(argv),
        "recording": "recording.rrd" if config.record else None,
        "unit": config.unit,
        "figures": [],
    }
    if figures:
        note = "quick sizes: a smoke test, not a result" if config.quick else None
        draw_figures(out, curriculum, summary, results, note, config.unit)
        run["figures"] = sorted(p.relative_to(out).as_posix() for p in out.glob("figures/*.png"))
    report = markdown_report(config.scenario, labels, config.k, summary, run)
    write_text_atomic(out / "report.md", report)
    if truth is not None:
        truth.log_run_card(f"{report}\n## Run card\n\n```json\n{card}\n```\n")
        truth.close()
        if config.record:
            parts = [out / TRUTH_PART]
            parts += [r.job.folder(out) / "recording.rrd" for r in results if r.predictions]
            merge_recordings(parts, out / "recording.rrd")
            parts[0].unlink()
    return metrics


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
