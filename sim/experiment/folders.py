"""Run folders: where a run writes, the proof that a folder is ours (its marker, its lock), and
what ``--resume`` and ``--overwrite`` may therefore remove. Folders never mix runs, and nothing
a user wrote is removed: only what the marker records, or what every run writes."""

from __future__ import annotations

import fcntl
import hashlib
import json
import os
import re
import shutil
import time
from dataclasses import asdict
from pathlib import Path
from typing import TYPE_CHECKING, Any

from c2inet.errors import InputError
from c2inet.files import (
    TEMPORARY_SUFFIX,
    writable_folder,
    write_text_atomic,
)

if TYPE_CHECKING:
    from sim.experiment.config import Execution, ExperimentConfig

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
    "calls.json",  # a benchmark tuning's calls: commit, wall, runs
    "tuning.db",  # a tuning's Optuna studies (in its own marked folder)
    "tuning.json",
    "mlflow.db",  # --logger mlflow's store, the run's or its sweep's
    ".mlflow-parents.lock",  # --logger mlflow: its jobs share one parent run a run folder
}
RUN_FOLDERS = {"jobs", "matrices", "figures", "logs", "tensorboard", "cache", "cells"}
RUN_FOLDERS |= {"mlartifacts", "wandb"}  # the trackers' copies of a run's report and figures
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
    for own in (MARKER, LOCK):  # damaged where only this project writes: never guessed at
        if (out / own).exists() and not (out / own).is_file():
            raise InputError(
                f"--out {out}: its {own} is not a file, so the folder is damaged; move it "
                "aside (nothing in it is removed) and start the run again"
            )
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
    execution_table = {k: v for k, v in asdict(execution).items() if k != "tracking"}
    data = {"experiment": config.to_json(), "execution": _plain(execution_table)}
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


def remove_leftovers(out: Path) -> list[Path]:
    """Remove the temporary files that interrupted atomic writes left in a run folder of ours
    (``.NAME.XXXXXXXX.c2i-tmp``: never a user's ``.notes.20241201``); returns them."""
    leftovers = [p for p in out.rglob(".*") if p.is_file() and TEMPORARY.match(p.name)]
    for path in leftovers:
        path.unlink()
    return leftovers


def _run_output(entry: Path, marked: set[str]) -> bool:
    """A file or folder a run writes into its own folder (or that its marker, ``marked``,
    records)."""
    if entry.is_file():
        return entry.name in RUN_FILES | marked or bool(TEMPORARY.match(entry.name))
    return entry.is_dir() and entry.name in RUN_FOLDERS


def foreign_entry(folder: Path, runs_only: bool = False) -> Path | None:
    """The first entry of ``folder`` that a run of ours does not write (None: all ours).

    Ours: the marker and the run's own files and folders, temporary files of an interrupted
    write, and nested run folders (a sweep's, a tuning's trials), alone or grouped in plain
    folders, at any depth, that hold nothing else (``runs_only``)."""
    marked = set(marked_files(folder))  # read once, not once an entry
    for entry in sorted(folder.iterdir()):
        run = entry.is_dir() and not entry.is_symlink() and (entry / MARKER).is_file()
        if entry.is_symlink():
            return entry
        if run:
            inner = foreign_entry(entry)
        elif runs_only:
            grouped = entry.is_dir() and any(entry.iterdir())
            inner = foreign_entry(entry, runs_only=True) if grouped else entry
        elif _run_output(entry, marked):
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
