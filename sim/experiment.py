"""The experiment as a function: a typed configuration, its jobs, and :func:`run_experiment`.

The unit of work is one job = (curriculum, method, seed): a function of the configuration with
its own child seed, its own folder (checkpoints, result, recording) and its own result, so a
local loop, local processes and Ray run the same jobs (``sim.backends``) and give the same
numbers. ``sim.run`` and ``sim.sweep`` are thin command lines over these functions;
``sim.outputs`` writes what a run leaves behind.

From a notebook::

    from sim.experiment import ExperimentConfig, run_experiment
    metrics = run_experiment(ExperimentConfig("crowd_noise_0.1..0.3", quick=True))
"""

from __future__ import annotations

import json
import os
import sys
import time
import zipfile
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import torch
from tqdm import tqdm

from c2inet.backbones import BACKBONES
from c2inet.errors import InputError, did_you_mean
from c2inet.files import writable_folder, write_atomic, write_text_atomic
from c2inet.methods.base import get_method
from c2inet.model import ModelConfig
from c2inet.options import build
from c2inet.trainer import ContinualTrainer, Result, TrainConfig
from sim.backends import BACKENDS, check_ray_address, run_jobs
from sim.curriculum import SAMPLE_SCENES, Curriculum, JobInputs, make_showcases, make_tasks
from sim.estimate import describe, run_seconds
from sim.outputs import TRUTH_PART, claim, output_folder, write_outputs
from sim.scenario import DomainSpec, parse_scenario
from viz.colours import method_colour
from viz.live import check_reachable, viewer_url
from viz.loggers import LOGGERS, make_loggers
from viz.observer import RecordingObserver, log_truth
from viz.recording import RunRecorder, default_blueprint

DEFAULT_METHODS = ("c2inet-online", "finetune", "cv")
APP_ID = "c2i-testbed"
# options that have a flag of their own: a --set of them would be silently overridden
FLAG_OPTIONS = (("train", "epochs"), ("train", "k"), ("train", "seed"), ("model", "backbone"))


@dataclass(frozen=True)
class ExperimentConfig:
    """What an experiment computes: equal configurations give equal ``metrics.json``.

    ``settings`` are option overrides by scope (``data``, ``model``, ``train`` or a method's
    name), as ``--set SCOPE.KEY=VALUE`` gives them. ``epochs`` and ``k`` default to 20 (2 and 5 when
    ``quick``). Everything is checked on construction: bad input raises ``InputError``.
    """

    scenario: str
    methods: tuple[str, ...] = DEFAULT_METHODS
    seeds: int = 1
    seed: int = 0
    epochs: int | None = None
    k: int | None = None
    backbone: str = "stgat"
    quick: bool = False
    settings: dict[str, dict[str, Any]] = field(default_factory=dict)
    scenarios_dir: tuple[Path, ...] = ()
    record: bool = True

    def __post_init__(self):
        fill = object.__setattr__  # the resolved defaults belong to the frozen configuration
        fill(self, "methods", tuple(self.methods))
        fill(self, "scenarios_dir", tuple(Path(p) for p in self.scenarios_dir))
        fill(self, "epochs", self.epochs if self.epochs is not None else (2 if self.quick else 20))
        fill(self, "k", self.k if self.k is not None else (5 if self.quick else 20))
        self.specs()  # a bad scenario or data override fails here
        if not self.methods:
            raise InputError("methods: no method named")
        if len(set(self.methods)) != len(self.methods):
            raise InputError(f"methods: a method is named twice in {','.join(self.methods)}")
        for name in self.methods:
            try:
                get_method(name)
            except KeyError as error:
                raise InputError(f"methods: {error.args[0]}") from None
        if self.backbone not in BACKBONES:
            raise InputError(f"backbone {self.backbone!r}: expected one of {sorted(BACKBONES)}")
        for scope in self.settings:
            if scope not in ("data", "model", "train", *self.methods):
                raise InputError(
                    f"--set: scope {scope!r} is not data, model, train or a chosen method"
                )
        for scope, key in FLAG_OPTIONS:
            if key in self.settings.get(scope, {}):
                raise InputError(f"--set {scope}.{key}: use --{key} (its flag) instead")
        if self.seed < 0:
            raise InputError(f"seed must be at least 0, got {self.seed}")
        for name, value, low in (
            ("seeds", self.seeds, 1),
            ("epochs", self.epochs, 0),
            ("k", self.k, 1),
        ):
            if value < low:
                raise InputError(f"{name} must be at least {low}, got {value}")
        try:
            self.model_config()
            self.train_config()
            for name in self.methods:
                self.method(name)
        except ValueError as error:
            raise InputError(f"--set {error}") from None

    def specs(self) -> list[DomainSpec]:
        """The curriculum's domains, with the ``data`` settings applied to their knobs."""
        return parse_scenario(self.scenario, list(self.scenarios_dir), self.settings.get("data"))

    def model_config(self) -> ModelConfig:
        return build(
            ModelConfig, {"backbone": self.backbone, **self.settings.get("model", {})}, "model"
        )

    def train_config(self, seed_index: int = 0) -> TrainConfig:
        """The trainer's options of the job with seed ``seed_index`` (its own seed)."""
        train = {**self.settings.get("train", {}), "epochs": self.epochs, "k": self.k}
        return build(TrainConfig, {**train, "seed": self.seed + seed_index}, "train")

    def method(self, name: str):
        return get_method(name)(self.model_config(), self.settings.get(name))

    def jobs(self) -> list[Job]:
        return [Job(m, s) for m in self.methods for s in range(self.seeds)]

    def to_json(self) -> dict[str, Any]:
        return {**asdict(self), "scenarios_dir": [str(p) for p in self.scenarios_dir]}


@dataclass(frozen=True)
class Execution:
    """How an experiment runs; none of it changes a number of ``metrics.json``.

    ``jobs``: local processes (``local``) or the CPUs of the local cluster Ray starts (``ray``,
    unless ``ray_address`` joins an existing one). ``workers``: processes that generate episodes.
    ``rerun``: also stream to a live viewer (``spawn`` or ``connect[=URL]``).
    """

    backend: str = "local"
    jobs: int = 1
    ray_address: str | None = None
    threads: int = 1
    workers: int = os.cpu_count() or 1
    cache: Path = Path(".cache/domains")
    rerun: str | None = None
    loggers: tuple[str, ...] = ()  # csv, tensorboard: per job, beside its checkpoints
    memory_budget: float | None = None  # GB one domain's generation may take (None: no limit)

    def __post_init__(self):
        object.__setattr__(self, "loggers", tuple(self.loggers))
        object.__setattr__(self, "cache", Path(self.cache))
        for name in self.loggers:
            if name not in LOGGERS:
                hint = did_you_mean(name, LOGGERS)
                raise InputError(f"--logger {name!r}: unknown{hint} (known: {', '.join(LOGGERS)})")
        if self.backend not in BACKENDS:
            raise InputError(f"--backend {self.backend!r}: expected one of {', '.join(BACKENDS)}")
        if self.rerun is not None and self.rerun != "spawn":
            if self.rerun != "connect" and not self.rerun.startswith("connect="):
                raise InputError(
                    f"--rerun {self.rerun[:80]!r}: expected spawn, connect or connect=URL"
                )
            viewer_url(self.rerun)
        if self.cache.exists() and not self.cache.is_dir():
            raise InputError(f"--cache {self.cache}: not a folder")
        if self.ray_address is not None and self.backend != "ray":
            raise InputError("--ray-address: only with --backend ray")
        if self.ray_address is not None:
            check_ray_address(self.ray_address)  # before the domains and the folder

    def job_options(self, resume: bool) -> dict[str, Any]:
        """The keyword options of :func:`run_job` that come from how the run executes."""
        live, loggers = self.live_target(), self.loggers
        return {"threads": self.threads, "resume": resume, "live": live, "loggers": loggers}

    def live_target(self) -> str | None:
        """Where jobs stream to: the spawned viewer's default address, or the given one."""
        return None if self.rerun is None else "connect" if self.rerun == "spawn" else self.rerun


@dataclass(frozen=True)
class Job:
    """One (method, seed) of an experiment; the curriculum is the experiment's."""

    method: str
    seed_index: int

    def folder(self, out: Path) -> Path:
        return out / "jobs" / self.method / f"seed_{self.seed_index}"


def parse_settings(items: list[str]) -> dict[str, dict[str, Any]]:
    """``SCOPE.KEY=VALUE`` strings -> {scope: {key: value}}, values read as bool, int, float or
    text (the option's type is checked when the configuration is built)."""
    settings: dict[str, dict[str, Any]] = {}
    for item in items:
        key, sep, text = item.partition("=")
        scope, dot, name = key.partition(".")
        if not sep or not dot or not name:
            raise InputError(
                f"--set {item!r}: expected SCOPE.KEY=VALUE, e.g. c2inet-online.pruning=false"
            )
        if name in settings.get(scope, {}):
            raise InputError(f"--set {key}: given twice; give each option once")
        settings.setdefault(scope, {})[name] = parse_value(text)
    return settings


def parse_value(text: str) -> bool | int | float | str:
    """An option value from the command line: true/false, an integer, a number, or text."""
    flag = {"true": True, "false": False}.get(text.strip().lower())
    if flag is not None:
        return flag
    for kind in (int, float):
        try:
            return kind(text)
        except ValueError:
            pass
    return text


def prepare(config: ExperimentConfig, execution: Execution) -> Curriculum:
    """Generate (or read from the content-hashed cache) every domain of the curriculum."""
    specs = config.specs()
    writable_folder(execution.cache, "--cache")
    tasks, domains = make_tasks(
        specs,
        config.seed,
        config.quick,
        execution.cache,
        execution.workers,
        execution.memory_budget,
    )
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

    def save(self, folder: Path) -> None:
        """``predictions.npz``, then ``result.json``, whose presence marks the job finished."""

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
        }
        write_text_atomic(folder / "result.json", json.dumps(data) + "\n")

    @staticmethod
    def load(job: Job, folder: Path) -> JobResult:
        """Read a finished job back; a damaged or foreign file is one :class:`InputError`
        naming it and the way out."""
        path = folder / "result.json"
        try:
            data = json.loads(path.read_text())
            matrices = {m: np.array(v, dtype=float) for m, v in data.pop("matrices").items()}
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
        return JobResult(job, result, predictions)


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
) -> JobResult:
    """Train one method with one seed through the curriculum, in ``job.folder(out)``.

    With ``resume``, a finished job is read back and an unfinished one continues after its last
    task checkpoint. The job's recording (the first seed's, when recorded) is written under a
    temporary name and renamed when the job is complete.
    """
    torch.set_num_threads(threads)
    folder = job.folder(out)
    if resume and (folder / "result.json").exists():
        return JobResult.load(job, folder)
    observers = [] if on_event is None else [on_event]
    names = [t.name for t in inputs.tasks]
    logs = make_loggers(loggers, folder, config.epochs, names)
    observers += logs
    recorder = drawing = None
    if (config.record or live) and job.seed_index == 0:  # the first seed is drawn
        partial = folder / "recording.partial.rrd" if config.record else None
        recorder = RunRecorder.create(APP_ID, recording_id(config), partial, live, None)
        colour = method_colour(config.methods.index(job.method))
        drawing = RecordingObserver(
            recorder,
            job.method,
            inputs.showcases,
            config.k,
            config.epochs,
            colour,
            seed=config.seed,
        )
        observers.append(drawing)
    trainer = ContinualTrainer(
        config.method(job.method),
        inputs.tasks,
        config.train_config(job.seed_index),
        checkpoint_dir=folder / "checkpoints",
        observers=observers,
        progress=None if on_event is None else _epoch_bar,
    )
    result = JobResult(job, trainer.run(resume=resume))
    for log in logs:
        log.close()
    if recorder is not None:
        recorder.close()
        if partial is not None:
            os.replace(partial, folder / "recording.rrd")
        result.predictions = drawing.final_predictions
    result.save(folder)
    return result


def _epoch_bar(iterable, **options):
    return tqdm(iterable, file=sys.stderr, unit="epoch", **options)


def follow(bar: tqdm) -> Callable[[str, dict], None]:
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
    recorder = RunRecorder.create(
        APP_ID,
        recording_id(config),
        path,
        live,
        default_blueprint(tasks, list(config.methods), SAMPLE_SCENES),
    )
    recorder.log_legend(list(config.methods))
    for domain in curriculum.domains:
        recorder.log_domain(domain.name, domain.knobs, domain.stats)
    log_truth(recorder, curriculum.inputs.showcases, curriculum.rollouts)
    return recorder


def run_experiment(
    config: ExperimentConfig,
    out: Path | None = None,
    execution: Execution | None = None,
    resume: bool = False,
    overwrite: bool = False,
    argv: list[str] | None = None,
) -> dict[str, Any]:
    """Generate the curriculum, run every job on the chosen backend, write every output.

    ``out``: the run's folder (default: a fresh ``runs/<scenario>/<timestamp>``, see
    ``sim.outputs.output_folder``); a folder holding anything else is refused unless
    ``overwrite``. With ``resume``, finished jobs are read back and unfinished ones continue from
    their last task; the configuration must equal the folder's. Returns ``metrics.json``.
    """
    execution = execution or Execution()
    if execution.rerun not in (None, "spawn"):
        check_reachable(viewer_url(execution.rerun))
    out = output_folder(config.scenario, out, resume)
    claim(out, config, execution, resume, overwrite)
    torch.set_num_threads(execution.threads)
    started = time.perf_counter()
    curriculum = prepare(config, execution)
    truth = None
    if config.record or execution.rerun:
        path = out / TRUTH_PART if config.record else None
        truth = record_truth(config, curriculum, path, execution.rerun)
    jobs = config.jobs()
    tasks = len(curriculum.inputs.tasks)
    if not resume:
        estimate = run_seconds(config, curriculum.inputs.tasks, execution.jobs)
        print(
            f"{len(jobs)} jobs x {tasks} tasks, {execution.jobs} at a time: about "
            f"{describe(estimate)} of training and evaluation (timed on this machine)",
            file=sys.stderr,
        )
    with tqdm(total=len(jobs) * tasks, desc="tasks", unit="task", file=sys.stderr) as bar:
        results = run_jobs(
            run_job,
            jobs,
            shared=(config, curriculum.inputs, out),
            backend=execution.backend,
            processes=execution.jobs,
            ray_address=execution.ray_address,
            options=execution.job_options(resume),
            progress=follow(bar),
            tasks_of=lambda _job: tasks,
        )
    wall = time.perf_counter() - started
    return write_outputs(out, config, execution, curriculum, results, truth, wall, argv or sys.argv)
