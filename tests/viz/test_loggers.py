"""The trackers on their own: what they keep, read back from their stores."""

from pathlib import Path

import pytest

from viz.loggers import REGISTRY as LOGGERS
from viz.loggers import MLflowLogger, WandbLogger, flat_params, prepare_tracking
from viz.loggers.checker import check_logger


def test_flat_params_name_each_setting_by_its_scope():
    tree = {"model": {"c_dim": 8, "sizes": [1, 2]}, "train": {"lr": 0.003}, "none": None}
    assert flat_params(tree) == {
        "model.c_dim": 8,
        "model.sizes": "[1, 2]",
        "train.lr": 0.003,
        "none": "None",
    }


def test_mlflow_keeps_every_parameter_and_metric_in_requests_a_server_takes(
    tmp_path: Path, monkeypatch
):
    """A tracking server takes 100 parameters and 1,000 metrics a request (the local store
    takes more, so each request is watched): a job with more loses none, and a resumed job's
    earlier run is replaced, not doubled."""
    MlflowClient = pytest.importorskip("mlflow.tracking").MlflowClient  # 3 s: only where used
    run = tmp_path / "runs" / "20261202-000000"
    job = run / "jobs" / "finetune" / "seed_0"
    job.mkdir(parents=True)
    prepare_tracking(("mlflow",), run)
    params = {f"p{i:03d}": i for i in range(250)}
    tasks = [f"t{i}" for i in range(400)]
    row = {metric: [0.5] * 400 for metric in ("ade", "fde", "ade_k1")}  # 1,200 numbers
    sizes, batch = [], MlflowClient.log_batch

    def watched(client, run_id, metrics=(), params=(), **kwargs):
        sizes.append((len(metrics), len(params)))
        return batch(client, run_id, metrics=metrics, params=params, **kwargs)

    monkeypatch.setattr(MlflowClient, "log_batch", watched)
    for _ in range(2):  # the second is the job resumed
        logger = MLflowLogger(job, 2, tasks, run_folder=run, params=params)
        logger("task_end", {"task": 0, "row": row})
        logger.close()
    assert all(m <= 1000 and p <= 100 for m, p in sizes)
    assert max(m for m, _ in sizes) == 1000 and max(p for _, p in sizes) == 100
    experiment = logger.client.get_experiment_by_name("runs/20261202-000000")
    runs = logger.client.search_runs([experiment.experiment_id])
    (tracked,) = [r for r in runs if "c2i_job" in r.data.tags]  # beside its run folder's
    assert len(tracked.data.params) == 250 and tracked.data.params["p249"] == "249"
    assert len(tracked.data.metrics) == 1200


def test_two_run_folders_of_one_name_logging_to_one_store_keep_each_others_runs(tmp_path):
    """``projA/exp/r`` and ``projB/exp/r`` share an experiment name in a shared store; a job of
    one (resumed) replaces only its own earlier run, never the other folder's."""
    pytest.importorskip("mlflow")
    uri = f"sqlite:///{tmp_path / 'shared.db'}"
    runs = [tmp_path / project / "exp" / "r" for project in ("projA", "projB")]
    for run in [*runs, runs[0]]:  # projA's job runs again: resumed
        job = run / "jobs" / "finetune" / "seed_0"
        job.mkdir(parents=True, exist_ok=True)
        MLflowLogger.experiment(run, uri)
        logger = MLflowLogger(job, 1, ["a"], run_folder=run, uri=uri)
        logger("epoch_end", {"task": 0, "epoch": 0, "nll": 1.0})
        logger.close()
    experiment = logger.client.get_experiment_by_name("exp/r")
    tracked = logger.client.search_runs([experiment.experiment_id])
    folders = [r.data.tags["c2i_folder"] for r in tracked if "c2i_job" in r.data.tags]
    assert sorted(folders) == sorted(str(run.resolve()) for run in runs)
    parents = [r.data.tags["c2i_folder"] for r in tracked if "c2i_parent" in r.data.tags]
    assert sorted(parents) == sorted(str(run.resolve()) for run in runs)  # one a folder, kept


def test_a_resumed_job_has_one_wandb_run_not_two(tmp_path: Path):
    """A resumed job replays its finished tasks' events: its W&B folder is started afresh, so
    the job holds one run, not an interrupted one beside a complete one."""
    pytest.importorskip("wandb")
    run = tmp_path / "crowd" / "stamp"
    job = run / "jobs" / "finetune" / "seed_0"
    for value in (1.0, 2.0):
        logger = WandbLogger(job, 2, ["a"], run_folder=run, params={"train.lr": 0.01})
        logger("epoch_end", {"task": 0, "epoch": 0, "nll": value})
        logger.close()
    (only,) = (job / "wandb").glob("offline-run-*/run-*.wandb")
    assert only.stat().st_size > 0 and not (job / "wandb" / "wandb").exists()


def test_an_unreachable_tracking_server_is_one_error_after_a_bounded_wait(tmp_path):
    """A refused connection: one InputError naming the store within seconds, where MLflow's
    own retries waited minutes."""
    pytest.importorskip("mlflow")
    import time

    from c2inet.errors import InputError

    started = time.monotonic()
    with pytest.raises(InputError, match=r"--logger mlflow=http://127.0.0.1:1: cannot use"):
        prepare_tracking(("mlflow=http://127.0.0.1:1",), tmp_path / "runs" / "r")
    assert time.monotonic() - started < 30


@pytest.mark.parametrize("answer", ["500", "never"])
def test_a_failing_or_silent_tracking_server_is_one_error_after_a_bounded_wait(
    answer, tmp_path, monkeypatch
):
    """A server that answers every request with 500, and one that accepts and never answers:
    one InputError within a bounded wait (the request timeout, one retry), not minutes."""
    pytest.importorskip("mlflow")
    import socket
    import threading
    import time

    from c2inet.errors import InputError

    monkeypatch.setenv("MLFLOW_HTTP_REQUEST_TIMEOUT", "2")
    server = socket.create_server(("127.0.0.1", 0))
    held = []

    def serve():
        while True:
            try:
                connection, _ = server.accept()
            except OSError:  # closed: the test is over
                return
            held.append(connection)
            if answer == "500":
                connection.recv(65536)
                connection.sendall(
                    b"HTTP/1.1 500 Internal Server Error\r\nContent-Length: 0\r\n"
                    b"Connection: close\r\n\r\n"
                )
                connection.close()

    threading.Thread(target=serve, daemon=True).start()
    uri = f"http://127.0.0.1:{server.getsockname()[1]}"
    started = time.monotonic()
    try:
        with pytest.raises(InputError, match=rf"--logger mlflow={uri}: cannot use"):
            prepare_tracking((f"mlflow={uri}",), tmp_path / "runs" / "r")
    finally:
        server.close()
        for connection in held:
            connection.close()
    assert time.monotonic() - started < 30


def test_wandb_online_without_a_key_is_one_error_naming_the_login(tmp_path, monkeypatch):
    pytest.importorskip("wandb")
    from c2inet.errors import InputError

    monkeypatch.setenv("HOME", str(tmp_path))  # no ~/.netrc
    monkeypatch.delenv("WANDB_API_KEY", raising=False)
    monkeypatch.setenv("WANDB_MODE", "online")
    run = tmp_path / "crowd" / "stamp"
    with pytest.raises(InputError, match=r"--logger wandb=online: W&B cannot start a run.*log in"):
        WandbLogger(run / "jobs" / "finetune" / "seed_0", 2, ["a"], run_folder=run, uri="online")


@pytest.mark.parametrize("name", LOGGERS.names())
def test_every_registered_logger_passes_the_checker(name, tmp_path, monkeypatch):
    """Each logger, as the registry finds it, takes a job's events and writes its own files."""
    monkeypatch.setenv("WANDB_SILENT", "true")
    written = check_logger(LOGGERS.get(name), tmp_path)
    assert all(tmp_path in p.parents for p in written)
