"""``--logger mlflow[=URI]``: an MLflow run per job, in the run's own store or on a server."""

from __future__ import annotations

import hashlib
import logging
import os
import time
from pathlib import Path
from typing import Any

from c2inet.errors import InputError, one_line
from viz.loggers.base import Logger, register, scalars

# MLflow's HTTP client waits minutes for a server by default (7 retries, 120 s timeouts)
MLFLOW_PATIENCE = {
    "MLFLOW_HTTP_REQUEST_MAX_RETRIES": "1",
    "MLFLOW_HTTP_REQUEST_BACKOFF_FACTOR": "1",
    "MLFLOW_HTTP_REQUEST_TIMEOUT": "10",
}


@register
class MLflowLogger(Logger):
    """An MLflow run per job, in the run's own store ``mlflow.db`` (SQLite; ``mlflow ui
    --backend-store-uri sqlite:///RUN/mlflow.db``) or on the server of ``mlflow=URI``: the
    configuration as parameters, every number as a metric at its step. The experiment is the
    run folder (``scenario/timestamp``)."""

    name = "mlflow"
    title = "an MLflow run per job, in the run's mlflow.db or on the server of mlflow=URI"
    value = "URI"  # a tracking server, not the run's own store

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

    @classmethod
    def prepare(cls, run_folder: Path, value: str | None) -> None:
        """The store and experiment, by the run itself before its jobs race to create them."""
        cls.experiment(run_folder, value)


def _param(key: str, value: Any):
    from mlflow.entities import Param

    return Param(key, str(value)[:6000])  # MLflow's limit on a parameter's value
