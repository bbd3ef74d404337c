"""Loggers on the trainer's observer hook: what a job measures, as a CSV file or TensorBoard
events, beside the recording.

Both log the same numbers at the same global step (task * epochs + epoch): per epoch the
training losses and the validation ADE of every seen task, per task the error-matrix row and the
diagnostics (lists averaged over the tasks seen). A resumed job replays its finished tasks'
events, so each logger starts its output afresh and ends up complete.
"""

from __future__ import annotations

import csv
import os
import shutil
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

from c2inet.errors import InputError

LOGGERS = ("csv", "tensorboard")
ROW_METRICS = ("ade", "fde", "ade_k1", "fde_k1", "ade_draw", "fde_draw")


def epoch_step(task: int, epoch: int, epochs: int) -> int:
    """The global epoch of ``epoch`` of task ``task``, counted across the curriculum."""
    return task * epochs + epoch


def task_step(task: int, epochs: int) -> int:
    """The global epoch that ended task ``task``: where its results are logged."""
    return max(0, epoch_step(task + 1, -1, epochs))


def diagnostic_scalars(diagnostics: dict[str, Any]) -> Iterator[tuple[str, float]]:
    """The numbers of a task's diagnostics; per-task lists averaged over the tasks seen."""
    for key, value in diagnostics.items():
        if isinstance(value, list):
            value = float(np.mean(value)) if value else None
        if isinstance(value, int | float):
            yield key, float(value)


def scalars(event: str, data: dict[str, Any], epochs: int, tasks: list[str]) -> Iterator:
    """(step, name, value) of every number of a trainer event."""
    if event == "epoch_end":
        step = epoch_step(data["task"], data["epoch"], epochs)
        for key, value in data.items():
            if key not in ("task", "epoch"):
                yield step, key, float(value)
    elif event == "task_end":
        step = task_step(data["task"], epochs)
        for metric in ROW_METRICS:
            for name, value in zip(tasks, data["row"].get(metric, []), strict=False):
                yield step, f"matrix_{metric}/{name}", float(value)
        for key, value in diagnostic_scalars(data.get("diagnostics") or {}):
            yield step, f"diagnostics/{key}", value


class CSVLogger:
    """``log.csv``: one row per number (step, task, event, name, value), written under a
    temporary name and renamed when the job is complete."""

    def __init__(self, folder: Path, epochs: int, tasks: list[str]):
        self.path, self.epochs, self.tasks = folder / "log.csv", epochs, tasks
        self.partial = folder / "log.partial.csv"
        folder.mkdir(parents=True, exist_ok=True)
        self.file = self.partial.open("w", newline="")
        self.writer = csv.writer(self.file)
        self.writer.writerow(["step", "task", "event", "name", "value"])

    def __call__(self, event: str, data: dict[str, Any]) -> None:
        for step, name, value in scalars(event, data, self.epochs, self.tasks):
            self.writer.writerow([step, data["task"], event, name, value])

    def close(self) -> None:
        self.file.close()
        os.replace(self.partial, self.path)


class TensorBoardLogger:
    """``tensorboard/``: event files for ``tensorboard --logdir`` (one run per job)."""

    def __init__(self, folder: Path, epochs: int, tasks: list[str]):
        try:
            from torch.utils.tensorboard import SummaryWriter
        except ImportError:
            raise InputError(
                "--logger tensorboard: TensorBoard is not installed (pip install '.[tensorboard]')"
            ) from None
        self.folder, self.epochs, self.tasks = folder / "tensorboard", epochs, tasks
        shutil.rmtree(self.folder, ignore_errors=True)  # a resumed job logs everything again
        self.writer = SummaryWriter(str(self.folder))

    def __call__(self, event: str, data: dict[str, Any]) -> None:
        for step, name, value in scalars(event, data, self.epochs, self.tasks):
            self.writer.add_scalar(name, value, step)

    def close(self) -> None:
        self.writer.close()


def make_loggers(names: tuple[str, ...], folder: Path, epochs: int, tasks: list[str]) -> list:
    kinds = {"csv": CSVLogger, "tensorboard": TensorBoardLogger}
    return [kinds[name](folder, epochs, tasks) for name in names]
