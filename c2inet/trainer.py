"""The continual trainer: tasks in order, L epochs each, then every task's test split evaluated.

One trainer serves every method; methods add behaviour through hooks (``c2inet.methods.base``).
Each task keeps its last epoch, or with ``select = "val"`` its epoch of lowest error on its own
validation split (``c2inet.selection``); the learning rate follows a schedule that starts anew
each task (``c2inet.schedule``). No task's data is looked at outside its turn, except by methods
that declare ``sees_old_tasks`` (the joint reference).
"""

from __future__ import annotations

import math
import zlib
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import torch

from c2inet.augment import AUGMENTATIONS, augment_scenes
from c2inet.batch import Batch, batches
from c2inet.checkpoints import CheckpointStore, load_checkpoint
from c2inet.data import Windows
from c2inet.device import (
    check_device_name,
    cuda_rng_state,
    model_device,
    placed,
    resolve_device,
)
from c2inet.diagnostics import diagnose
from c2inet.errors import InputError
from c2inet.evaluation import evaluate, evaluate_all
from c2inet.methods.base import Method, TaskContext
from c2inet.metrics import average_seen, forgetting_final
from c2inet.options import Tunable, check_range, choose, require
from c2inet.schedule import SCHEDULES, learning_rate, set_learning_rate
from c2inet.selection import SELECTION_METRICS, SELECTIONS, BestEpoch, selection_score

# wide enough that no tuned rate sat at a bound at batch 16 or 64 (docs/benchmark.md)
TRAIN_SPACE = {"train.lr": Tunable(1e-5, 5e-2, log=True)}  # tuned for every method that trains
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
    # the learning rate within each task (c2inet.schedule): constant, cosine or linear from lr
    # to lr * lr_final at the task's end, after `warmup` epochs rising linearly from 0
    schedule: str = "constant"
    warmup: float = 0.0
    lr_final: float = 0.01
    # the epoch a task keeps (c2inet.selection): its last, or the one of lowest best-of-select_k
    # error on its own validation split: ade, fde, or their sum (ade+fde)
    select: str = "last"
    select_k: int = 20
    select_metric: str = "ade"
    # each epoch's scenes turned (c2inet.augment): none, rotate (any angle) or axes (quarter
    # turns and mirror images)
    augment: str = "none"

    def __post_init__(self):
        check_device_name(self.device)
        choose(self, "schedule", SCHEDULES)
        choose(self, "select", SELECTIONS)
        choose(self, "select_metric", SELECTION_METRICS)
        choose(self, "augment", AUGMENTATIONS)
        require(self, 0, "epochs", "seed", "val_every", "warmup")
        require(self, 0, "lr_final", high=1)
        require(self, 1, "select_k")
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
    with torch.device(placed(resolve_device(cfg.device))):
        model = method.build_model()
    optimiser = None
    if method.trains:
        optimiser = torch.optim.Adam(model.parameters(), lr=cfg.lr, fused=cfg.fused_adam)
    return model, optimiser, rng


def train_step(
    method: Method, ctx: TaskContext, batch: Batch, cfg: TrainConfig
) -> dict[str, float]:
    """One optimiser step on ``batch`` with the method's step hooks; returns the loss's parts
    (floats, or detached scalars on the model's device that :func:`train_epoch` reads once an
    epoch: a step reads nothing back to the host for its logs)."""
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


def train_epoch(
    method: Method, ctx: TaskContext, data: Windows, cfg: TrainConfig, epoch: int = 0
) -> dict:
    """One pass over ``data`` in shuffled batches (:func:`train_step`), epoch ``epoch`` of the
    task, each step at its scheduled learning rate; returns the mean of each loss part over the
    steps, and the rate of the last step (``lr``)."""
    totals: dict[str, float] = {}
    steps, count = 0, math.ceil(len(data) / cfg.batch_scenes)
    lr = cfg.lr
    if cfg.augment != "none":
        data = augment_scenes(data, ctx.rng, cfg.augment)
    for batch in batches(data, cfg.batch_scenes, ctx.rng, ctx.device):
        if ctx.optimiser is not None:
            elapsed = epoch + steps / count
            lr = learning_rate(cfg.lr, cfg.schedule, elapsed, cfg.epochs, cfg.warmup, cfg.lr_final)
            set_learning_rate(ctx.optimiser, lr)
        for key, value in train_step(method, ctx, batch, cfg).items():
            totals[key] = totals.get(key, 0.0) + value  # on the device: no read per step
        steps += 1
    return {**{k: float(v) / max(steps, 1) for k, v in totals.items()}, "lr": lr}


SUMMARISED = ("ade", "fde", "ade_k1", "fde_k1", "col_pred_primary", "col_truth_primary")


def task_summary(matrices: dict[str, np.ndarray], i: int) -> dict[str, float]:
    """After task ``i``: each metric averaged over the tasks seen so far (``seen/METRIC``, the
    paper's Table-2 number; after the last task the run's final score) and the forgetting of
    ADE so far (``forgetting/METRIC``: each earlier task's error now minus its best before, the
    mean; 0 after the first task). What a tracker's table of runs sorts by."""
    out = {
        f"seen/{m}": float(np.mean(matrices[m][i, : i + 1])) for m in SUMMARISED if m in matrices
    }
    for m in ("ade", "ade_k1"):
        if m in matrices:
            lost = forgetting_final(matrices[m][: i + 1, : i + 1]) if i else np.zeros(1)
            out[f"forgetting/{m}"] = float(np.mean(lost))
    return out


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
        # the task checkpoints, of this identity (the job, its options, its data)
        self.store = CheckpointStore(checkpoint_dir, identity, len(tasks))
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
                    model, other.test, cfg.k, cfg.seed + j, cfg.eval_batch_scenes, cfg.test_rules, j
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
            if self.store.folder is not None:
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
                "summary": task_summary(result.matrices, i),
                "model": model,
                "diagnostics": result.diagnostics[i] if result.diagnostics else {},
            },
        )

    def _replay(self, model, optimiser, rng: np.random.Generator, result: Result) -> int:
        """Restore the state after the last finished task and return the next task's index.

        Each finished task's events are sent again, with the model and method state of its own
        checkpoint, so observers (the recording) see what an uninterrupted run shows.
        """
        paths = self.store.verified()
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
        val = self.tasks[ctx.index].val
        if cfg.select == "val" and val is None:
            raise InputError(f"train.select=val: task {ctx.name} has no validation split")
        best = BestEpoch()
        for epoch in self.progress(
            range(cfg.epochs), desc=f"{method.name} {ctx.name}", leave=False
        ):
            losses = train_epoch(method, ctx, data, cfg, epoch)
            method.after_epoch(ctx, epoch)
            record = {"task": ctx.index, "epoch": epoch, **losses}
            if cfg.select == "val":
                scores = evaluate(
                    model, val, cfg.select_k, cfg.seed, cfg.eval_batch_scenes, point_draws=0
                )
                record["select_ade"], record["select_fde"] = scores["ade"], scores["fde"]
                score = selection_score(scores, cfg.select_metric)
                best.offer(score, epoch, model, ctx.optimiser, method)
            if cfg.val_every and (epoch + 1) % cfg.val_every == 0:
                for seen in self.tasks[: ctx.index + 1]:
                    if seen.val is not None:
                        record[f"val_ade/{seen.name}"] = evaluate(
                            model, seen.val, 1, cfg.seed, cfg.eval_batch_scenes, point_draws=0
                        )["ade"]
            self.history.append(record)
            self._notify("epoch_end", record)
        if best.epoch is not None:
            best.restore(model, ctx.optimiser, method)
            self.history[-1]["selected_epoch"] = best.epoch
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
        self.store.save(index, state)
