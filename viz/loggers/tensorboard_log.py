"""``--logger tensorboard``: TensorBoard event files, one run per job."""

from __future__ import annotations

import shutil
from pathlib import Path
from typing import Any

import numpy as np

from c2inet.errors import InputError
from viz.loggers.base import Logger, register, scalars


@register
class TensorBoardLogger(Logger):
    """``tensorboard/``: event files for ``tensorboard --logdir`` (one run per job), with the
    job's configuration and final scores in the HParams tab."""

    name = "tensorboard"
    title = "TensorBoard event files, one run per job, the configuration as HParams"

    def __init__(self, folder: Path, epochs: int, tasks: list[str], params=None, **_):
        try:
            from torch.utils.tensorboard import SummaryWriter
        except ImportError:
            raise InputError(
                "--logger tensorboard: TensorBoard is not installed (pip install '.[tensorboard]')"
            ) from None
        self.folder, self.epochs, self.tasks = folder / "tensorboard", epochs, tasks
        shutil.rmtree(self.folder, ignore_errors=True)  # a resumed job logs everything again
        self.writer = SummaryWriter(str(self.folder))
        self.params, self.final = params or {}, {}

    def __call__(self, event: str, data: dict[str, Any]) -> None:
        for step, name, value in scalars(event, data, self.epochs, self.tasks):
            self.writer.add_scalar(name, value, step)
        if event == "task_end":  # the latest row: the final one once the job ends
            row = data["row"]
            self.final = {f"final/{m}": float(np.mean(row[m])) for m in ("ade", "ade_k1")}

    def close(self) -> None:
        if self.params:
            self.writer.add_hparams(self.params, self.final, run_name=".")
        self.writer.close()
