"""``--logger csv``: every number in ``log.csv`` beside the job's metrics."""

from __future__ import annotations

import csv
import os
from pathlib import Path
from typing import Any

from viz.loggers.base import Logger, register, scalars


@register
class CSVLogger(Logger):
    """``log.csv``: one row per number (step, task, event, name, value), written under a
    temporary name and renamed when the job is complete."""

    name = "csv"
    title = "every number in the job's log.csv (step, task, event, name, value)"

    def __init__(self, folder: Path, epochs: int, tasks: list[str], **_):
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
