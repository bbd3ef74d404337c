"""The continual trainer: tasks in order, L epochs each, then every task's test split evaluated.

One trainer serves every method; methods add behaviour through hooks (``c2inet.methods.base``).
Model selection is the last epoch of each task; no task's data is looked at outside its turn,
except by methods that declare ``sees_old_tasks`` (the joint reference).
"""

from __future__ import annotations

import itertools
import json
import math
import zlib
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import torch

from c2inet.batch import Batch, batches
from c2inet.data import Windows
from c2inet.device import check_device_name, cuda_rng_state, model_device, resolve_device
from c2inet.diagnostics import diagnose
from c2inet.errors import InputError
from c2inet.evaluation import evaluate, evaluate_all
from c2inet.files import file_digest, write_atomic, write_text_atomic
from c2inet.methods.base import Method, TaskContext
from c2inet.metrics import average_seen
from c2inet.options import Tunable, check_range, require

# wide enough that no tuned rate sat at a bound at batch 16 or 64 (docs/benchmark.md)
TRAIN_SPACE = {"train.lr": Tunable(1e-4, 5e-2, log=True)}  # tuned for every method that trains
LAST_EPOCH = ("kl_c_binding",)  # loss parts of a task's last epoch kept in its diagnostics


@dataclass
class Task:
    """One domain as the learner sees it: windows per split (val may be None).

    ``value`` is the domain's knob value where it has one (diagnostics regress it from C).
    """

    name: str
    train: Windows
    val: Windows | None
    test: Windows
    value: float | None = None


@dataclass
class TrainConfig:
    epochs: int = 20  # L, per task
    batch_scenes: int = 16
    lr: float = 3e-3
    k: int = 20  # samples for best-of-K
    k_train: int = 5  # samples of the variety loss (best of k_train per scene), every method
    seed: int = 0
    eval_batch_scenes: int = 256
    val_every: int = 1  # epochs between validation curves (0: never)
    diagnostics: bool = True  # measure the confounder's diagnostics after each task
    test_rules: bool = True  # also score the latent models' other test-time rules for C
    eval_unseen: bool = True  # after each task, also score the tasks not yet learnt (NaN if not)
    device: str = "cpu"  # auto, cpu, cuda, cuda:N or mps (c2inet.device)
    # Adam in one kernel for all the weights (the loop over small tensors was 8 % of a step);
    # false: the loop, as runs before December 2026 (the same steps to float32 rounding)
    fused_adam: bool = True
    # a tuning trial's pruning: stop after task t when the average point-prediction error over
    # tasks 0..t (the objective so far) is above stop_above[t] (None or no entry: go on)
    stop_above: tuple[float | None, ...] = ()

    def __post_init__(self):
        check_device_name(self.device)
        require(self, 0, "epochs", "seed", "val_every")
        for bound in self.stop_above:
            if bound is not None:
                check_range("stop_above", bound, 0, math.inf)
        require(self, 1, "batch_scenes", "k", "k_train", "eval_batch_scenes")
        require(self, 0, "lr", high=10, open_low=True)


@dataclass
class Result:
    """Everything a run measured: one (tasks x tasks) matrix per metric, and the history."""

    tasks: list[str]
    matrices: dict[str, np.ndarray]
    summaries: list[dict[str, Any]] = field(default_factory=list)
    history: list[dict[str, Any]] = field(default_factory=list)
    diagnostics: list[dict[str, Any]] = field(default_factory=list)  # one per task


Observer = Callable[[str, dict[str, Any]], None]


def _generator(seed: int, method: str) -> np.random.Generator:
    return np.random.default_rng(
        np.random.SeedSequence(seed, spawn_key=(zlib.crc32(method.encode()),))
    )


def start_training(method: Method, cfg: TrainConfig):
    """A fresh model on ``cfg.device``, its optimiser (None for a method that does not train)
    and the run's random generator, seeded from ``cfg.seed`` in a fixed order: every run of a
    seed starts alike."""
    torch.manual_seed(cfg.seed)
    rng = _generator(cfg.seed, method.name)
    with torch.device(resolve_device(cfg.device)):
        model = method.build_model()
    optimiser = None
    if method.trains:
        optimiser = torch.optim.Adam(model.parameters(), lr=cfg.lr, fused=cfg.fused_adam)
    return model, optimiser, rng


def train_step(
    method: Method, ctx: TaskContext, batch: Batch, cfg: TrainConfig
) -> dict[str, float]:
    """One optimiser step on ``batch`` with the method's step hooks; returns the loss's parts."""
    ctx.batch = batch
    ctx.loss, ctx.parts, ctx.output = method.step_loss(ctx, batch, cfg.k_train)
    method.before_backward(ctx)
    ctx.optimiser.zero_grad()
    ctx.loss.backward()
    method.after_backward(ctx)
    ctx.optimiser.step()
    method.after_step(ctx)
    parts = ctx.parts
    ctx.batch = ctx.output = ctx.loss = None
    return parts


def train_epoch(method: Method, ctx: TaskContext, data: Windows, cfg: TrainConfig) -> dict:
    """One pass over ``data`` in shuffled batches (:func:`train_step`); returns the mean of each
    loss part over the steps."""
    totals: dict[str, float] = {}
    steps = 0
    for batch in batches(data, cfg.batch_scenes, ctx.rng, ctx.device):
        for key, value in train_step(method, ctx, batch, cfg).items():
            totals[key] = totals.get(key, 0.0) + value
        steps += 1
    return {k: v / max(steps, 1) for k, v in totals.items()}


class ContinualTrainer:
    """Runs one method through a curriculum and fills the task-by-task error matrices."""

    def __init__(
        self,
        method: Method,
        tasks: list[Task],
        config: TrainConfig,
        checkpoint_dir: Path | None = None,
        observers: list[Observer] | None = None,
        progress: Callable[[Any], Any] | None = None,
        identity: str = "",
    ):
        self.method, self.tasks, self.config = method, tasks, config
        self.checkpoint_dir = checkpoint_dir
        self.identity = identity  # what the checkpoints belong to (the job, its options, its data)
        self.observers = observers or []
        self.progress = progress or (lambda iterable, **_: iterable)
        self.history: list[dict[str, Any]] = []
        self.model: torch.nn.Module | None = None  # the trained model, once ``run`` returns

    def _notify(self, event: str, data: dict[str, Any]) -> None:
        for observer in self.observers:
            observer(event, data)

    def run(self, resume: bool = False) -> Result:
        """Train through every task; with ``resume``, continue after the last task checkpoint
        in ``checkpoint_dir``, giving exactly the result of an uninterrupted run."""
        cfg, method = self.config, self.method
        model, optimiser, rng = start_training(method, cfg)
        n = len(self.tasks)
        result = Result([t.name for t in self.tasks], {})
        start = self._replay(model, optimiser, rng, result) if resume else 0
        for i in range(start, n):
            if self._pruned(i - 1, result):
                break
            task = self.tasks[i]
            seen = self.earlier_training_data(i) if method.sees_old_tasks else []
            ctx = TaskContext(i, task.name, task.train, model, optimiser, rng, seen, tasks=n)
            if method.trains:
                self._train_task(ctx)
            for j, other in enumerate(self.tasks if cfg.eval_unseen else self.tasks[: i + 1]):
                scores = evaluate_all(
                    model, other.test, cfg.k, cfg.seed + j, cfg.eval_batch_scenes, cfg.test_rules
                )
                for metric, value in scores.items():
                    result.matrices.setdefault(metric, np.full((n, n), np.nan))[i, j] = value
            kept = method.memory_floats(model)
            if method.sees_old_tasks:  # joint keeps every finished task's training data
                kept += sum(w.positions.size for w in self.earlier_training_data(i + 1))
            result.summaries.append({**method.summary(), "memory_floats": kept})
            if cfg.diagnostics:
                seen_tasks = self.tasks[: i + 1]
                tests, values = [t.test for t in seen_tasks], [t.value for t in seen_tasks]
                diagnosis = diagnose(model, tests, values, cfg.seed)
                result.diagnostics.append({**diagnosis, **self._last_epoch(i)})
            if self.checkpoint_dir is not None:
                self._save(model, optimiser, rng, i, result)
            self._task_end(i, model, result)
        result.history = self.history
        self.model = model
        return result

    def _last_epoch(self, index: int) -> dict[str, float]:
        """What training measured in task ``index``'s last epoch that says whether a clamped
        term acted: the share of scenes whose KL_C had a gradient (``kl_c_binding``)."""
        last = [r for r in self.history if r["task"] == index]
        return {k: last[-1][k] for k in LAST_EPOCH if last and k in last[-1]}

    def _pruned(self, index: int, result: Result) -> bool:
        """Whether the run stops after task ``index`` (-1: before the first): its objective
        so far, the average point-prediction error over tasks 0..index, is above the bound."""
        bounds = self.config.stop_above
        if not 0 <= index < len(bounds) or bounds[index] is None:
            return False
        return not average_seen(result.matrices["ade_k1"])[index] <= bounds[index]  # NaN too

    def earlier_training_data(self, index: int) -> list[Windows]:
        """The training data of the tasks before ``index``: what only a method that declares
        ``sees_old_tasks`` (the joint reference) is given."""
        return [t.train for t in self.tasks[:index]]

    def _task_end(self, i: int, model: torch.nn.Module, result: Result) -> None:
        self._notify(
            "task_end",
            {
                "task": i,
                "name": self.tasks[i].name,
                "row": {m: result.matrices[m][i].tolist() for m in result.matrices},
                "model": model,
                "diagnostics": result.diagnostics[i] if result.diagnostics else {},
            },
        )

    def _checkpoint(self, index: int) -> Path:
        return self.checkpoint_dir / f"task_{index:02d}.pt"

    def checkpoints(self) -> list[Path]:
        """The verified task checkpoints in ``checkpoint_dir``: task 0, 1, ... up to the first
        one the manifest does not list (a kill between the two writes), each checked against
        its SHA-256, and all of them against this trainer's ``identity``."""
        if self.checkpoint_dir is None:
            return []
        paths = list(
            itertools.takewhile(Path.exists, map(self._checkpoint, range(len(self.tasks))))
        )
        if not paths:
            return []
        if not (self.checkpoint_dir / MANIFEST).exists():
            return []  # killed before its first manifest, or an earlier version's: retrain
        manifest = self._manifest()
        if manifest.get("identity") != self.identity:
            raise InputError(
                f"--resume: {self.checkpoint_dir} holds checkpoints of another job, other options "
                "or other data; delete the folder to retrain that job, or use --overwrite"
            )
        listed = list(itertools.takewhile(lambda p: p.name in manifest["sha256"], paths))
        for path in listed:
            if file_digest(path) != manifest["sha256"][path.name]:
                raise InputError(
                    f"--resume: checkpoint {path} is damaged (its SHA-256 differs from the "
                    "manifest's); delete it to retrain from the task before, or use --overwrite"
                )
        return listed

    def _manifest(self) -> dict[str, Any]:
        path = self.checkpoint_dir / MANIFEST
        try:
            manifest = json.loads(path.read_text())
            if not isinstance(manifest, dict) or not isinstance(manifest.get("sha256"), dict):
                raise ValueError("no sha256 table")
        except (OSError, ValueError) as error:
            raise InputError(
                f"--resume: {path} is damaged ({type(error).__name__}); delete "
                f"{self.checkpoint_dir} to retrain that job, or use --overwrite"
            ) from None
        return manifest

    def _replay(self, model, optimiser, rng: np.random.Generator, result: Result) -> int:
        """Restore the state after the last finished task and return the next task's index.

        Each finished task's events are sent again, with the model and method state of its own
        checkpoint, so observers (the recording) see what an uninterrupted run shows.
        """
        paths = self.checkpoints()
        for path in paths:
            state = load_checkpoint(path, model_device(model))
            try:
                model.load_state_dict(state["model"])
                self.method.load_state_dict(state["method"], model)
            except (RuntimeError, ValueError, KeyError, TypeError) as error:
                raise InputError(
                    f"--resume: checkpoint {path} does not fit this run's model or method "
                    f"({type(error).__name__}); delete it to retrain, or use --overwrite"
                ) from None
            i = state["task"]
            result.matrices = {m: v.cpu().numpy().copy() for m, v in state["matrices"].items()}
            result.summaries, result.diagnostics = state["summaries"], state["diagnostics"]
            for record in state["history"]:
                if record["task"] == i:
                    self.history.append(record)
                    self._notify("epoch_end", record)
            self._task_end(i, model, result)
        if paths:
            if optimiser is not None:
                optimiser.load_state_dict(state["optimiser"])
            torch.set_rng_state(state["torch_rng"].cpu())
            if state.get("cuda_rng") is not None:
                torch.cuda.set_rng_state(state["cuda_rng"].cpu(), model_device(model))
            rng.bit_generator.state = state["numpy_rng"]
        return len(paths)

    def _train_task(self, ctx: TaskContext) -> None:
        cfg, method, model = self.config, self.method, ctx.model
        model.train()
        method.before_task(ctx)
        data = method.training_windows(ctx)
        for epoch in self.progress(
            range(cfg.epochs), desc=f"{method.name} {ctx.name}", leave=False
        ):
            losses = train_epoch(method, ctx, data, cfg)
            method.after_epoch(ctx, epoch)
            record = {"task": ctx.index, "epoch": epoch, **losses}
            if cfg.val_every and (epoch + 1) % cfg.val_every == 0:
                for seen in self.tasks[: ctx.index + 1]:
                    if seen.val is not None:
                        record[f"val_ade/{seen.name}"] = evaluate(
                            model, seen.val, 1, cfg.seed, cfg.eval_batch_scenes, point_draws=0
                        )["ade"]
            self.history.append(record)
            self._notify("epoch_end", record)
        method.after_task(ctx)

    def _save(self, model, optimiser, rng: np.random.Generator, index: int, result: Result):
        """All a resumed run needs after task ``index``: model, optimiser, method state (e.g. the
        queue), RNG states, and the matrices, summaries, diagnostics and history so far."""
        state = {
            "task": index,
            "model": model.state_dict(),
            "optimiser": None if optimiser is None else optimiser.state_dict(),
            "method": self.method.state_dict(model),
            "torch_rng": torch.get_rng_state(),
            "cuda_rng": cuda_rng_state(model_device(model)),
            "numpy_rng": rng.bit_generator.state,
            "matrices": {m: torch.from_numpy(v.copy()) for m, v in result.matrices.items()},
            "summaries": list(result.summaries),
            "diagnostics": list(result.diagnostics),
            "history": list(self.history),
        }
        path = self._checkpoint(index)
        write_atomic(path, lambda tmp: torch.save(state, tmp))
        fresh = index == 0 or not (self.checkpoint_dir / MANIFEST).exists()
        digests = {} if fresh else self._manifest()["sha256"]
        digests = {name: d for name, d in digests.items() if name < path.name}
        manifest = {"identity": self.identity, "sha256": {**digests, path.name: file_digest(path)}}
        write_text_atomic(self.checkpoint_dir / MANIFEST, json.dumps(manifest, indent=1) + "\n")


MANIFEST = "manifest.json"  # beside the checkpoints: the job's identity and their SHA-256
CHECKPOINT_KEYS = {"task", "model", "optimiser", "method", "torch_rng", "numpy_rng", "matrices"}


def load_checkpoint(path: Path, device: torch.device | str = "cpu") -> dict[str, Any]:
    """Read a task checkpoint safely (tensors and plain values only) onto ``device``; a damaged
    or foreign one is one :class:`InputError` naming it and the way out."""
    try:
        state = torch.load(path, weights_only=True, map_location=device)
        missing = CHECKPOINT_KEYS - set(state)
    except Exception as error:  # torch raises many kinds for a damaged file
        raise InputError(
            f"--resume: checkpoint {path} is damaged ({type(error).__name__}); delete it to "
            "retrain from the task before, or use --overwrite"
        ) from None
    if missing:
        raise InputError(f"--resume: {path} is no checkpoint of this project (no {min(missing)})")
    return state
