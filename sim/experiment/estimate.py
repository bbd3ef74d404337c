"""How long a run will take, measured before it starts.

Each method trains on this machine through every task for a few steps each, with its hooks:
the steps from the second task on carry what a method adds once it has a past (replay, a
teacher's forward pass, projected gradients), and its task and epoch hooks (Fisher, buffers,
Eq 8 fits) are timed as they run; each task is timed on its own scenes, so a stream of unlike
ones (ETH-UCY's univ of 28 agents a window, then eth of 2) costs what each task costs. One
evaluation of each task's test split follows; the run's cost follows from how often each
happens (steps per epoch, epochs, evaluations of every task after every task, validation of the
tasks seen). Timed in CPU seconds of this process (one
torch thread), so a machine busy with other work does not inflate it; the wall time follows
from the jobs run at once. An estimate: later tasks change it.
"""

from __future__ import annotations

import itertools
import math
import statistics
import time
from collections.abc import Callable

import torch

from c2inet.batch import batches
from c2inet.diagnostics import diagnose
from c2inet.evaluation import evaluate, evaluate_all
from c2inet.methods.base import Method, TaskContext
from c2inet.trainer import Task, TrainConfig, start_training, train_step

STEPS = 9  # timed training steps, after one to warm up, at a task's start and at its end


def _seconds(work: Callable[[], object]) -> float:
    """The CPU seconds of one call of ``work`` (this process's: one torch thread)."""
    start = time.process_time()
    work()
    return time.process_time() - start


def _step_seconds(method: Method, ctx: TaskContext, data, train: TrainConfig) -> float:
    """The mean CPU seconds of :data:`STEPS` training steps, each with its batch's making, as a
    job spends them, after a first step that warms up. The mean: a step's cost grows with its
    scenes' agents (and attention with their square), so on crowds of unlike sizes (density's 3
    to 19, univ's windows of up to 28) a few steps' median sits below what an epoch's steps cost
    on average (the estimate was 46 % low on density, 22 % on ETH-UCY)."""
    steps = itertools.islice(batches(data, train.batch_scenes, ctx.rng, ctx.device), STEPS + 1)
    times = []
    while True:
        started = time.process_time()
        batch = next(steps, None)
        if batch is None:
            break
        train_step(method, ctx, batch, train)
        times.append(time.process_time() - started)
    return statistics.fmean(times[1:] or times)


def task_seconds(
    method: Method, ctx: TaskContext, train: TrainConfig, epochs: int
) -> tuple[float, int, float]:
    """Train on task ``ctx`` as a job does, briefly: its task hooks, steps timed before and after
    every epoch hook has run once. Returns (seconds a step, steps an epoch, seconds of hooks).

    The steps are those of the windows the method trains on, as the trainer takes them: a replay
    method's buffer (coresets train on it beside the task's scenes: counting the task's alone
    made density's estimate 23 % low), joint's growing union, none for a task joint-scratch
    skips. Every epoch hook runs, so what they build up is there for the later steps (C2INet's
    queue gains a component every second epoch, and its steps grow dearer through a task: timing
    the first steps and two hooks made its jobs 35 to 44 % dearer than estimated); a step costs
    the mean of the first steps and the last."""
    started = time.process_time()
    ctx.model.train()
    method.before_task(ctx)
    data = method.training_windows(ctx)
    hooks = time.process_time() - started
    steps_per_epoch = math.ceil(len(data) / train.batch_scenes)
    if not len(data):  # a task it does not train on (joint-scratch's final_only): time a step
        data = ctx.train
    first = _step_seconds(method, ctx, data, train)
    hooks += sum(_seconds(lambda e=e: method.after_epoch(ctx, e)) for e in range(epochs))
    hooked = type(method).after_epoch is not Method.after_epoch  # else nothing grows: no retiming
    last = _step_seconds(method, ctx, data, train) if epochs > 1 and hooked else first
    hooks += _seconds(lambda: method.after_task(ctx))
    return (first + last) / 2, steps_per_epoch, hooks


def method_seconds(config, name: str, tasks: list[Task], warm_up: bool = False) -> float:
    """The estimated time of one job of method ``name`` through ``tasks`` (one thread): a few
    steps and the hooks of every task timed as it trains (a stream of unlike scenes, ETH-UCY's,
    costs what each of its tasks costs), and one evaluation of each task's test split, counted
    as often as the run evaluates it. With ``warm_up``, an evaluation and diagnostics run
    untimed first: a process's first ones import and allocate what later ones reuse
    (scikit-learn alone: 0.7 s, counted once a task)."""
    method, train = config.method(name), config.train_config()
    n, first = len(tasks), tasks[0]
    with torch.random.fork_rng(devices=[]):
        model, optimiser, rng = start_training(method, train)
        total = 0.0
        if method.trains:
            for i, task in enumerate(tasks):
                seen = [t.train for t in tasks[:i]] if method.sees_old_tasks else []
                ctx = TaskContext(i, task.name, task.train, model, optimiser, rng, seen, tasks=n)
                per_step, steps, hooks = task_seconds(method, ctx, train, config.epochs)
                total += per_step * steps * config.epochs + hooks
                if task.val is not None and train.val_every:  # the tasks seen, every val_every
                    val = _seconds(lambda t=task: evaluate(model, t.val, 1, 0, point_draws=0))
                    total += val * config.epochs / train.val_every * (n - i)
                if task.val is not None and train.select == "val":  # select_k samples, each epoch
                    picks = train.select_k
                    select = _seconds(
                        lambda t=task, k=picks: evaluate(model, t.val, k, 0, point_draws=0)
                    )
                    total += select * config.epochs

        def evaluation(task: Task) -> None:
            evaluate_all(model, task.test, config.k, 0, variants=train.test_rules)

        def diagnostics(task: Task) -> None:
            if train.diagnostics:
                diagnose(model, [task.test], [task.value], 0)

        if warm_up:
            evaluation(first)
            diagnostics(first)
        for j, task in enumerate(tasks):  # task j is evaluated after every task from j on
            times = n if train.eval_unseen else n - j
            once = _seconds(lambda t=task: evaluation(t)) + _seconds(lambda t=task: diagnostics(t))
            total += once * times
    return total


def job_seconds(config, tasks: list[Task]) -> dict[str, float]:
    """The estimated time of one job of each method of ``config`` (the first warms up)."""
    return {
        name: method_seconds(config, name, tasks, warm_up=i == 0)
        for i, name in enumerate(config.methods)
    }


def run_seconds(config, each: dict[str, float], parallel: int) -> float:
    """The estimated wall time of every job of ``config``, ``parallel`` at a time, each job of
    method m taking ``each[m]`` (:func:`job_seconds`) and the longest taken first."""
    return lanes_seconds(
        [each[name] for name in config.methods for _ in range(config.seeds)], parallel
    )


def lanes_seconds(jobs: list[float], parallel: int) -> float:
    """The wall time of jobs of these seconds, ``parallel`` at a time, the longest first."""
    lanes = [0.0] * max(1, parallel)
    for seconds in sorted(jobs, reverse=True):  # longest first, each to the least loaded worker
        lanes[lanes.index(min(lanes))] += seconds
    return max(lanes)


def describe(seconds: float) -> str:
    return f"{seconds:.0f} s" if seconds < 90 else f"{seconds / 60:.1f} min"
