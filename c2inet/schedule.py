"""The learning rate within a task: a linear warm-up, then constant, cosine or linear decay.

A pure function of the training time (epochs into the task, fractional), not one of torch's
stateful schedulers: every task starts its schedule anew, and a resumed run needs no scheduler
state to continue exactly where an uninterrupted one would be.
"""

from __future__ import annotations

import math

import torch

SCHEDULES = ("constant", "cosine", "linear")


def learning_rate(
    lr: float, schedule: str, elapsed: float, epochs: int, warmup: float, lr_final: float
) -> float:
    """The rate ``elapsed`` epochs into a task of ``epochs``: ``warmup`` epochs rising linearly
    from 0 to ``lr``, then ``schedule`` from ``lr`` to ``lr * lr_final`` at the task's end
    (``constant`` stays at ``lr``)."""
    if warmup > 0 and elapsed < warmup:
        return lr * (elapsed + 1e-3) / warmup  # never exactly 0: the first step still moves
    if schedule == "constant" or epochs <= warmup:
        return lr
    progress = min((elapsed - warmup) / (epochs - warmup), 1.0)
    if schedule == "cosine":
        share = lr_final + (1 - lr_final) * 0.5 * (1 + math.cos(math.pi * progress))
    else:  # linear
        share = 1 - (1 - lr_final) * progress
    return lr * share


def set_learning_rate(optimiser: torch.optim.Optimizer, lr: float) -> None:
    """Every parameter group of ``optimiser`` at ``lr``."""
    for group in optimiser.param_groups:
        group["lr"] = lr
