"""Loggers on the trainer's observer hook: what a job measures, as a CSV file, TensorBoard
events, an MLflow run or a W&B run, beside the recording.

All log the same numbers at the same global step (task * epochs + epoch): per epoch the
training losses and the validation ADE of every seen task, per task the error-matrix row and the
diagnostics (lists averaged over the tasks seen); TensorBoard, MLflow and W&B also the job's
configuration as hyper-parameters. A resumed job replays its finished tasks' events, so each
logger starts its output afresh and ends up complete.
"""

from __future__ import annotations

import csv
import hashlib
import logging
import os
import re
import shutil
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

from c2inet.errors import InputError, one_line

# mlflow=URI: a tracking server, not the run's own store; wandb=online: W&B's server, not offline
LOGGERS = ("csv", "tensorboard", "mlflow", "wandb")
WANDB_MODES = ("offline", "online")
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


def flat_params(tree: dict[str, Any], prefix: str = "") -> dict[str, str | int | float | bool]:
    """A nested configuration as ``scope.key`` parameters; lists and None as text."""
    out: dict[str, str | int | float | bool] = {}
    for key, value in tree.items():
        name = f"{prefix}{key}"
        if isinstance(value, dict):
            out.update(flat_params(value, f"{name}."))
        else:
            out[name] = value if isinstance(value, str | int | float | bool) else str(value)
    return out


class CSVLogger:
    """``log.csv``: one row per number (step, task, event, name, value), written under a
    temporary name and renamed when the job is complete."""

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


class TensorBoardLogger:
    """``tensorboard/``: event files for ``tensorboard --logdir`` (one run per job), with the
    job's configuration and final scores in the HParams tab."""

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


# MLflow's HTTP client waits minutes for a server by default (7 retries, 120 s timeouts)
MLFLOW_PATIENCE = {
    "MLFLOW_HTTP_REQUEST_MAX_RETRIES": "1",
    "MLFLOW_HTTP_REQUEST_BACKOFF_FACTOR": "1",
    "MLFLOW_HTTP_REQUEST_TIMEOUT": "10",
}


class MLflowLogger:
    """An MLflow run per job, in the run's own store ``mlflow.db`` (SQLite; ``mlflow ui
    --backend-store-uri sqlite:///RUN/mlflow.db``) or on the server of ``mlflow=URI``: the
    configuration as parameters, every number as a metric at its step. The experiment is the
    run folder (``scenario/timestamp``)."""

    def __init__(self, folder: Path, epochs: int, tasks: list[str], run_folder=None, **options):
        run_folder = Path(run_folder or folder).resolve()
        self.epochs, self.tasks = epochs, tasks
        self.client, experiment = self.experiment(run_folder, options.get("uri"))
        job = folder.resolve().relative_to(run_folder).as_posix()
        # the run folder's own tag: two folders of one name logging to one store stay apart
        owner = hashlib.sha256(str(run_folder).encode()).hexdigest()[:16]
        mine = f"tags.c2i_job = '{job}' and tags.c2i_run = '{owner}'"
        for old in self.client.search_runs([experiment], mine):
            self.client.delete_run(old.info.run_id)  # a resumed job logs everything again
        tags = {"c2i_job": job, "c2i_run": owner, "c2i_folder": str(run_folder)}
        run = self.client.create_run(experiment, run_name=job, tags=tags)
        self.run_id = run.info.run_id
        params = [_param(k, v) for k, v in (options.get("params") or {}).items()]
        for start in range(0, len(params), 100):  # MLflow takes 100 parameters a request
            self.client.log_batch(self.run_id, params=params[start : start + 100])

    @staticmethod
    def experiment(run_folder: Path, uri: str | None = None):
        """(client, experiment id) of the run, created when missing: by the run itself before
        its jobs start, since two jobs creating the store at once would race."""
        try:
            from mlflow.tracking import MlflowClient
        except ImportError:
            raise InputError(
                "--logger mlflow: MLflow is not installed (pip install '.[mlflow]')"
            ) from None
        logging.getLogger("mlflow").setLevel(logging.WARNING)  # its schema notices
        for key, value in MLFLOW_PATIENCE.items():  # a bounded wait for a server, not minutes
            os.environ.setdefault(key, value)
        target = uri or f"sqlite:///{run_folder / 'mlflow.db'}"
        name = f"{run_folder.parent.name}/{run_folder.name}"
        try:
            client = MlflowClient(target)
            found = client.get_experiment_by_name(name)
            return client, found.experiment_id if found else client.create_experiment(name)
        except Exception as error:  # a refused, failing or absent server, a bad store: its own
            why = one_line(str(error).strip().splitlines()[0] if str(error).strip() else "")
            raise InputError(
                f"--logger mlflow{'=' + uri if uri else ''}: cannot use the tracking store "
                f"{target[:80]} ({type(error).__name__}: {why[:160]})"
            ) from None

    def __call__(self, event: str, data: dict[str, Any]) -> None:
        from mlflow.entities import Metric

        now = int(time.time() * 1000)
        metrics = [
            Metric(name, value, now, step)
            for step, name, value in scalars(event, data, self.epochs, self.tasks)
        ]
        for start in range(0, len(metrics), 1000):  # and 1,000 metrics
            self.client.log_batch(self.run_id, metrics=metrics[start : start + 1000])

    def close(self) -> None:
        self.client.set_terminated(self.run_id)


class WandbLogger:
    """A W&B run per job, offline by default (``wandb/`` in the job's folder, no account needed;
    ``wandb sync`` uploads it later) or online with ``wandb=online`` and a login: the project is
    the run folder's parent (the scenario, for default folders), the group the run folder, the
    name the job; the configuration as the run's config, every number at its step."""

    def __init__(self, folder: Path, epochs: int, tasks: list[str], run_folder=None, **options):
        try:
            import wandb
        except ImportError:
            raise InputError(
                "--logger wandb: W&B is not installed (pip install '.[wandb]')"
            ) from None
        run_folder = Path(run_folder or folder).resolve()
        self.epochs, self.tasks = epochs, tasks
        shutil.rmtree(folder / "wandb", ignore_errors=True)  # a resumed job logs everything again
        (folder / "wandb").mkdir(parents=True)
        settings = wandb.Settings(
            mode=options.get("uri") or "offline",
            silent=True,
            console="off",  # the job's own output stays the job's
            x_disable_stats=True,  # no system metrics sampled beside training
            x_disable_meta=True,
            save_code=False,
            disable_git=True,
        )
        self.run = wandb.init(
            dir=folder,
            project=re.sub(r"[/\\#?%:]", "_", run_folder.parent.name)[:128],
            group=run_folder.name,
            name=folder.resolve().relative_to(run_folder).as_posix(),
            config=options.get("params") or {},
            settings=settings,
            reinit="create_new",
        )

    def __call__(self, event: str, data: dict[str, Any]) -> None:
        steps: dict[int, dict[str, float]] = {}
        for step, name, value in scalars(event, data, self.epochs, self.tasks):
            steps.setdefault(step, {})[name] = value
        for step, values in sorted(steps.items()):
            self.run.log(values, step=step)

    def close(self) -> None:
        self.run.finish()


def _param(key: str, value: Any):
    from mlflow.entities import Param

    return Param(key, str(value)[:6000])  # MLflow's limit on a parameter's value


def prepare_tracking(specs: tuple[str, ...], run_folder: Path) -> None:
    """Create what the jobs' trackers share (the MLflow store and experiment) before they run."""
    for spec in specs:
        name, _, uri = spec.partition("=")
        if name == "mlflow":
            MLflowLogger.experiment(run_folder.resolve(), uri or None)


def make_loggers(
    specs: tuple[str, ...],
    folder: Path,
    epochs: int,
    tasks: list[str],
    run_folder: Path | None = None,
    params: dict[str, Any] | None = None,
) -> list:
    """The loggers ``specs`` name, for the job in ``folder`` of the run in ``run_folder``."""
    kinds = {"csv": CSVLogger, "tensorboard": TensorBoardLogger, "mlflow": MLflowLogger}
    kinds["wandb"] = WandbLogger
    loggers = []
    for spec in specs:
        name, _, uri = spec.partition("=")
        options = {"run_folder": run_folder, "params": params, "uri": uri or None}
        loggers.append(kinds[name](folder, epochs, tasks, **options))
    return loggers
