"""``--logger mlflow[=URI]``: an MLflow run per job, in the run's own store or on a server."""

from __future__ import annotations

import fcntl
import hashlib
import logging
import os
import time
from pathlib import Path
from typing import Any

from c2inet.errors import InputError
from viz.loggers.base import Logger, failure, register, scalars

# MLflow's HTTP client waits minutes for a server by default (7 retries, 120 s timeouts)
MLFLOW_PATIENCE = {
    "MLFLOW_HTTP_REQUEST_MAX_RETRIES": "1",
    "MLFLOW_HTTP_REQUEST_BACKOFF_FACTOR": "1",
    "MLFLOW_HTTP_REQUEST_TIMEOUT": "10",
}


@register
class MLflowLogger(Logger):
    """An MLflow run per job, in the store ``mlflow.db`` of its group (the run's folder, or the
    sweep's or benchmark's it belongs to: SQLite, ``mlflow ui --backend-store-uri
    sqlite:///GROUP/mlflow.db``) or on the server of ``mlflow=URI``: the configuration as
    parameters, every number as a metric at its step. The experiment is the group's folder
    (``scenario/timestamp``, or the sweep's), so a sweep's runs compare side by side. Each run
    folder (a sweep's variant) is a parent run, named by its place in the group, whose children
    are its jobs, named short (``finetune seed 0``), and whose artifacts are the folder's report,
    figures and recording; a run starts when its job starts and ends when it ends."""

    name = "mlflow"
    title = "an MLflow run per job, in the run's mlflow.db or on the server of mlflow=URI"
    value = "URI"  # a tracking server, not the run's own store

    def __init__(self, folder: Path, epochs: int, tasks: list[str], run_folder=None, **options):
        run_folder = Path(run_folder or folder).resolve()
        group = Path(options.get("group") or run_folder).resolve()
        self.epochs, self.tasks = epochs, tasks
        self.client, experiment = self.experiment(group, options.get("uri"))
        parent = _parent_run(self.client, experiment, group, run_folder)
        self.run_id = _fresh_run(
            self.client, experiment, run_folder, run_folder, folder.resolve(), "c2i_job", parent
        )
        params = [_param(k, v) for k, v in (options.get("params") or {}).items()]
        for start in range(0, len(params), 100):  # MLflow takes 100 parameters a request
            self.client.log_batch(self.run_id, params=params[start : start + 100])

    @classmethod
    def prepare(cls, group: Path, value: str | None) -> None:
        """The store and experiment, by the group itself before its jobs race to create them."""
        cls.experiment(group, value)

    @classmethod
    def log_outputs(cls, run_folder: Path, group: Path, value: str | None, files: list[Path]):
        """The run's report, figures and recording as the artifacts of its parent run, which
        ends with them."""
        client, experiment = cls.experiment(group, value)
        run_id = _parent_run(client, experiment, group, run_folder)
        for path in files:
            where = path.parent.relative_to(run_folder).as_posix()
            client.log_artifact(run_id, str(path), None if where == "." else where)
        client.set_terminated(run_id)

    @staticmethod
    def experiment(group: Path, uri: str | None = None):
        """(client, experiment id) of the group, created when missing (its artifacts beside its
        own store, not in the working directory)."""
        try:
            from mlflow.tracking import MlflowClient
        except ImportError:
            raise InputError(
                "--logger mlflow: MLflow is not installed (pip install '.[mlflow]')"
            ) from None
        logging.getLogger("mlflow").setLevel(logging.WARNING)  # its schema notices
        for key, value in MLFLOW_PATIENCE.items():  # a bounded wait for a server, not minutes
            os.environ.setdefault(key, value)
        target = uri or f"sqlite:///{group / 'mlflow.db'}"
        name = f"{group.parent.name}/{group.name}"
        try:
            client = MlflowClient(target)
            found = client.get_experiment_by_name(name)
            if found:
                return client, found.experiment_id
            artifacts = None if uri else (group / "mlartifacts").as_uri()
            return client, client.create_experiment(name, artifact_location=artifacts)
        except Exception as error:  # a refused, failing or absent server, a bad store: its own
            raise InputError(
                f"--logger mlflow{'=' + uri if uri else ''}: cannot use the tracking store "
                f"{target[:80]} ({failure(error)})"
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


def _param(key: str, value: Any):
    from mlflow.entities import Param

    return Param(key, str(value)[:6000])  # MLflow's limit on a parameter's value


def _short(name: str) -> str:
    """A job's place in its run folder as a run's name: ``jobs/finetune/seed_0`` ->
    ``finetune seed 0``."""
    parts = name.removeprefix("jobs/").split("/")
    return " ".join(p.replace("seed_", "seed ") for p in parts)


def _fresh_run(
    client,
    experiment: str,
    base: Path,
    run_folder: Path,
    path: Path,
    kind: str,
    parent: str | None = None,
):
    """A new MLflow run for ``path`` (a job's folder) of ``run_folder``, tagged by its place in
    ``base`` and named short, a child of ``parent``; the earlier one of the same path and run
    folder is deleted first (a resumed job logs everything again). Tagged by the run folder's
    own hash, so two folders of one name logging to one store never delete each other's runs."""
    name = path.relative_to(base).as_posix() if path.is_relative_to(base) else path.name
    owner = hashlib.sha256(str(run_folder).encode()).hexdigest()[:16]
    for old in client.search_runs(
        [experiment], f"tags.{kind} = '{name}' and tags.c2i_run = '{owner}'"
    ):
        client.delete_run(old.info.run_id)
    tags = {kind: name, "c2i_run": owner, "c2i_folder": str(run_folder)}
    if parent is not None:
        tags["mlflow.parentRunId"] = parent
    return client.create_run(experiment, run_name=_short(name), tags=tags).info.run_id


def _parent_run(client, experiment: str, group: Path, run_folder: Path) -> str:
    """The run of ``run_folder`` (a sweep's variant, or the run itself), named by its place in
    ``group``, made by its first job (the jobs of a folder ask under a lock, so they share
    one) and found again by the others, by the report and by a resumed run."""
    name = run_folder.relative_to(group).as_posix() if run_folder.is_relative_to(group) else "."
    name = group.name if name == "." else name
    owner = hashlib.sha256(str(run_folder).encode()).hexdigest()[:16]
    query = f"tags.c2i_parent = '{name}' and tags.c2i_run = '{owner}'"
    group.mkdir(parents=True, exist_ok=True)
    with open(group / ".mlflow-parents.lock", "a") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        found = client.search_runs([experiment], query)
        if found:
            return found[0].info.run_id
        tags = {"c2i_parent": name, "c2i_run": owner, "c2i_folder": str(run_folder)}
        return client.create_run(experiment, run_name=name, tags=tags).info.run_id
