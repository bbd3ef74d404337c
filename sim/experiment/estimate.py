"""How long a run will take, measured before it starts.

Each method is timed on this machine for a few training steps, one evaluation and one set of
diagnostics on the first task; the run's cost follows from how often each happens (steps per
epoch, epochs, evaluations of every task after every task, validation of the tasks seen). It is
an estimate: later tasks, replay and a busy machine change it.
"""

from __future__ import annotations

import itertools
import math
import statistics
import time
from collections.abc import Callable

import torch

from c2inet.batch import batches
from c2inet.device import model_device
from c2inet.diagnostics import diagnose
from c2inet.methods.base import Method
from c2inet.trainer import Task, evaluate, evaluate_all, start_training

STEPS = 9  # timed training steps per method, after one to warm up (3 varied by 40 %)


def _seconds(work: Callable[[], object], repeat: int = 1) -> float:
    """The median time of ``repeat`` calls of ``work``: a moment the machine was busy with
    something else does not count."""
    times = []
    for _ in range(repeat):
        start = time.perf_counter()
        work()
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def training_steps(method: Method, tasks: list[Task], batch_scenes: int) -> int:
    """Training steps of one epoch of every task; a method that trains on every task seen so
    far (``sees_old_tasks``: joint) steps through the growing union."""
    sizes = [len(t.train) for t in tasks]
    if method.sees_old_tasks:
        sizes = list(itertools.accumulate(sizes))
    return sum(math.ceil(size / batch_scenes) for size in sizes)


def method_seconds(config, name: str, tasks: list[Task]) -> float:
    """The estimated time of one job of method ``name`` through ``tasks`` (one thread)."""
    method, train = config.method(name), config.train_config()
    n, first = len(tasks), tasks[0]
    with torch.random.fork_rng(devices=[]):
        model, optimiser, _ = start_training(method, train)
        total = 0.0
        if method.trains:
            batch = next(batches(first.train, train.batch_scenes, device=model_device(model)))

            def step() -> None:
                loss = model.loss(batch, train.k_train).loss
                optimiser.zero_grad()
                loss.backward()
                optimiser.step()

            step()
            per_step = _seconds(step, STEPS)
            steps = training_steps(method, tasks, train.batch_scenes)
            total += per_step * steps * config.epochs
            if first.val is not None and train.val_every:
                val = _seconds(lambda: evaluate(model, first.val, 1, 0, point_draws=0))
                total += val * config.epochs / train.val_every * n * (n + 1) / 2
        total += _seconds(lambda: evaluate_all(model, first.test, config.k, 0)) * n * n
        if train.diagnostics:
            once = _seconds(lambda: diagnose(model, [first.test], [first.value], 0))
            total += once * n * (n + 1) / 2
    return total


def job_seconds(config, tasks: list[Task]) -> dict[str, float]:
    """The estimated time of one job of each method of ``config``."""
    return {name: method_seconds(config, name, tasks) for name in config.methods}


def run_seconds(config, each: dict[str, float], parallel: int) -> float:
    """The estimated wall time of every job of ``config``, ``parallel`` at a time, each job of
    method m taking ``each[m]`` (:func:`job_seconds`) and the longest taken first."""
    jobs = sorted(
        (each[name] for name in config.methods for _ in range(config.seeds)), reverse=True
    )
    lanes = [0.0] * max(1, parallel)
    for seconds in jobs:  # longest first, each to the least loaded worker
        lanes[lanes.index(min(lanes))] += seconds
    return max(lanes)


def describe(seconds: float) -> str:
    return f"{seconds:.0f} s" if seconds < 90 else f"{seconds / 60:.1f} min"
