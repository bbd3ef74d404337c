"""One job = (curriculum, method, seed): its inputs, its training and its result.

A job is a function of the configuration with its own child seed, its own folder (checkpoints,
result, recording) and its own result, so a local loop, local processes and Ray run the same
jobs (``sim.experiment.backends``) and give the same numbers.
"""

from __future__ import annotations

import hashlib
import json
import os
import time
import zipfile
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import torch

from c2inet.errors import InputError
from c2inet.files import writable_folder, write_atomic, write_text_atomic
from c2inet.trainer import ContinualTrainer, Result
from sim.experiment.config import Execution, ExperimentConfig, Job
from sim.experiment.curriculum import (
    SAMPLE_SCENES,
    Curriculum,
    JobInputs,
    experiment_tasks,
    make_showcases,
)
from sim.progress import progress_bar
from viz.blueprint import default_blueprint
from viz.colours import method_colour
from viz.loggers import flat_params, make_loggers
from viz.observer import RecordingObserver, framing, log_truth
from viz.recording import RunRecorder

APP_ID = "c2i-testbed"


def prepare(config: ExperimentConfig, execution: Execution) -> Curriculum:
    """Generate (or read from the content-hashed cache) every domain of the curriculum."""
    specs = config.specs
    writable_folder(execution.cache, "--cache")
    tasks, domains = experiment_tasks(specs, config, execution)
    drawn = config.record or execution.rerun is not None
    showcases, rollouts = make_showcases(specs, tasks, config.seed) if drawn else ([], {})
    one_family = len({s.family.name for s in specs}) == 1
    labels = [s.label if one_family else s.name for s in specs]
    return Curriculum(specs, domains, JobInputs(tasks, showcases), rollouts, labels)


@dataclass
class JobResult:
    """What one job measured (``c2inet.trainer.Result``) and the predictions it drew."""

    job: Job
    result: Result
    predictions: dict[str, np.ndarray] = field(default_factory=dict)  # task -> (K, A, T, 2)
    cpu_seconds: float | None = None  # the job's training and evaluation (after a resume: its rest)

    def save(self, folder: Path, identity: str = "") -> None:
        """``predictions.npz``, then ``result.json``, whose presence marks the job finished;
        it carries the job's ``identity`` and the SHA-256 of its own content."""

        def write_predictions(tmp: Path) -> None:
            with tmp.open("wb") as file:  # a file object: np.savez would append .npz to a name
                np.savez(file, **self.predictions)

        if self.predictions:
            write_atomic(folder / "predictions.npz", write_predictions)
        r = self.result
        data = {
            "tasks": r.tasks,
            "matrices": {m: v.tolist() for m, v in r.matrices.items()},
            "summaries": r.summaries,
            "history": r.history,
            "diagnostics": r.diagnostics,
            "cpu_seconds": self.cpu_seconds,
            "identity": identity,
        }
        text = json.dumps(data)
        signed = {**data, "sha256": hashlib.sha256(text.encode()).hexdigest()}
        write_text_atomic(folder / "result.json", json.dumps(signed) + "\n")

    @staticmethod
    def load(job: Job, folder: Path, identity: str = "") -> JobResult:
        """Read a finished job back; a damaged or foreign file, or one of another job, other
        options or other data (its ``identity``), is one :class:`InputError` naming it and the
        way out."""
        path = folder / "result.json"
        try:
            data = json.loads(path.read_text())
            digest = data.pop("sha256")
            if hashlib.sha256(json.dumps(data).encode()).hexdigest() != digest:
                raise ValueError("its SHA-256 differs")
            owner = data.pop("identity")
            matrices = {m: np.array(v, dtype=float) for m, v in data.pop("matrices").items()}
            cpu_seconds = data.pop("cpu_seconds", None)  # absent in results of older versions
            result = Result(matrices=matrices, **data)
            predictions = {}
            path = folder / "predictions.npz"
            if path.exists():
                with np.load(path, allow_pickle=False) as saved:
                    predictions = dict(saved)
        except (
            OSError,
            ValueError,
            KeyError,
            TypeError,
            AttributeError,
            zipfile.BadZipFile,
        ) as error:
            raise InputError(
                f"--resume: {path} is damaged or not this project's ({type(error).__name__}); "
                f"delete {folder} to run that job again, or use --overwrite"
            ) from None
        if owner != identity:
            raise InputError(
                f"--resume: {folder / 'result.json'} is the result of another job, other options "
                f"or other data; delete {folder} to run that job again, or use --overwrite"
            )
        return JobResult(job, result, predictions, cpu_seconds)


def recording_id(config: ExperimentConfig) -> str:
    """Shared by the run's and its jobs' recordings, so the viewer shows them as one."""
    return f"{config.scenario}-seed{config.seed}"


def run_job(
    job: Job,
    config: ExperimentConfig,
    inputs: JobInputs,
    out: Path,
    threads: int = 1,
    resume: bool = False,
    live: str | None = None,
    loggers: tuple[str, ...] = (),
    on_event: Callable[[str, dict], None] | None = None,
    tracking: Path | None = None,
) -> JobResult:
    """Train one method with one seed through the curriculum, in ``job.folder(out)``.

    With ``resume``, a finished job is read back (run again if its recording is missing) and an
    unfinished one continues after its last task checkpoint. The job's recording (the first
    seed's, when recorded) is written under a temporary name and renamed when it is complete.
    """
    torch.set_num_threads(threads)
    folder = job.folder(out)
    identity = job_identity(job, config, inputs)
    drawn = config.record and job.seed_index == 0
    if resume and (folder / "result.json").exists():
        if not drawn or (folder / "recording.rrd").exists():
            return JobResult.load(job, folder, identity)
        resume = False  # finished, but its recording is lost: run it again to draw it
    observers = [] if on_event is None else [on_event]
    names = [t.name for t in inputs.tasks]
    params = job_params(job, config)
    logs = make_loggers(loggers, folder, config.epochs, names, out, params, tracking)
    observers += logs
    recorder, drawing, partial = drawer(job, config, inputs, folder, live)
    if drawing is not None:
        observers.append(drawing)
    trainer = ContinualTrainer(
        config.method(job.method),
        inputs.tasks,
        config.train_config(job.seed_index),
        checkpoint_dir=folder / "checkpoints",
        observers=observers,
        progress=None if on_event is None else _epoch_bar,
        identity=identity,
    )
    started = time.process_time()
    result = JobResult(job, trainer.run(resume=resume))
    result.cpu_seconds = round(time.process_time() - started, 2)
    for log in logs:
        log.close()
    if recorder is not None:
        recorder.close()
        if partial is not None:
            os.replace(partial, folder / "recording.rrd")
        result.predictions = drawing.final_predictions
    result.save(folder, identity)
    return result


def drawer(job: Job, config: ExperimentConfig, inputs: JobInputs, folder: Path, live):
    """(recorder, observer, partial path) that draw the job's training into its recording (a
    partial file renamed when complete) or a live viewer: the first seed's only; Nones else."""
    if not (config.record or live) or job.seed_index != 0:
        return None, None, None
    partial = folder / "recording.partial.rrd" if config.record else None
    recorder = RunRecorder.create(APP_ID, recording_id(config), partial, live, None)
    colour = method_colour(config.methods.index(job.method))
    drawing = RecordingObserver(
        recorder, job.method, inputs.showcases, config.k, config.epochs, colour, seed=config.seed
    )
    return recorder, drawing, partial


def job_params(job: Job, config: ExperimentConfig) -> dict[str, Any]:
    """What a tracker logs as the job's hyper-parameters: the experiment, its sizes (quick,
    reduced or full, scenes per split, every ``--set data.*``), the resolved model and training
    options, the method's own, and the job's method and seed."""
    train = asdict(config.train_config(job.seed_index))
    tree = {
        "scenario": config.scenario,
        "method": job.method,
        "seed": train.pop("seed"),
        "quick": config.quick,
        "size": config.size,
        "model": asdict(config.model_config()),
        "train": train,
        "data": config.settings.get("data", {}),  # every --set data.KEY given
        "splits": {  # the scenes per split of the first domain (a family's, or --set's)
            split: getattr(config.specs[0].family.splits, split)
            for split in ("train", "val", "test")
        },
        job.method: config.settings.get(job.method, {}),
    }
    return flat_params(tree)


# training options added since jobs were first identified, with the value that is the behaviour
# before them: hashed only when set otherwise, so a run begun before an option resumes
SINCE = {"select_metric": "ade"}


def job_identity(job: Job, config: ExperimentConfig, inputs: JobInputs) -> str:
    """The SHA-256 of all a job's numbers depend on: its method and seed, the experiment's
    configuration and every task's data. Its checkpoints and result carry it, so a resume
    never mixes in the work of another job, other options or changed data files."""
    what = {"job": [job.method, job.seed_index], "config": config.to_json()}
    train = vars(config.train_config(job.seed_index))  # a family's [train] table too
    what["train"] = {k: v for k, v in train.items() if k not in SINCE or v != SINCE[k]}
    digest = hashlib.sha256(json.dumps(what, sort_keys=True, default=str).encode())
    for task in inputs.tasks:
        digest.update(task.name.encode())
        for split in (task.train, task.val, task.test):
            if split is not None:
                digest.update(split.positions.tobytes())
                digest.update(split.scene_start.tobytes())
    return digest.hexdigest()


def _epoch_bar(iterable, **options):
    return progress_bar(iterable, unit="epoch", **options)


def follow(bar) -> Callable[[str, dict], None]:
    """A ``progress`` for ``run_jobs``: the tasks bar moves with finished tasks (its estimate of
    the time left is the whole run's) and shows the newest epoch's training loss."""

    def update(event: str, data: dict) -> None:
        if event == "task_end":
            bar.update(1)
        elif event == "job_end":
            bar.update(data["tasks"])
        elif event == "epoch_end" and "nll" in data:
            bar.set_postfix_str(f"loss {data['nll']:.3f}", refresh=False)

    return update


def record_truth(config: ExperimentConfig, curriculum: Curriculum, path: Path, live: str | None):
    """The run's own recording: the blueprint, the domains and the ground truth."""
    tasks = [t.name for t in curriculum.inputs.tasks]
    bounds = framing(curriculum.inputs.showcases, curriculum.rollouts)
    recorder = RunRecorder.create(
        APP_ID,
        recording_id(config),
        path,
        live,
        default_blueprint(tasks, list(config.methods), SAMPLE_SCENES, bounds),
    )
    recorder.log_legend(list(config.methods), tasks)
    recorder.log_scale_bars(bounds)
    for domain in curriculum.domains:
        recorder.log_domain(domain.name, domain.knobs, domain.stats)
    log_truth(recorder, curriculum.inputs.showcases, curriculum.rollouts)
    return recorder
