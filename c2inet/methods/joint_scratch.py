"""Joint training from scratch: each task trains a freshly initialised model on the union of all
tasks seen so far, for the same epochs (so the same steps) as the warm-started ``joint``.

``joint`` continues from the previous task's weights, so its later tasks are fine-tuning on
more data, and its forgetting measures how a warm start drifts; this one is the classic
multi-task upper bound of each row, whose forgetting is the variation of independent fits. It
keeps the initial weights (drawn from the seed) to start every task from them again. With
``final_only`` it trains once, at the last task, on the union of all: the one row a reference
block reads (the fair benchmark's), at a sixth of the cost on six tasks; the earlier rows are
then of the untrained model.
Hooks: ``before_task``, ``training_windows``. Example: ``--methods joint-scratch``
"""

from __future__ import annotations

import copy
from dataclasses import dataclass
from typing import Any

import numpy as np
import torch

from c2inet.data import Windows
from c2inet.errors import InputError
from c2inet.methods.base import TaskContext
from c2inet.methods.joint import Joint


@dataclass(frozen=True)
class JointScratchOptions:
    final_only: bool = False  # train once, at the last task, on the union of all


class JointScratch(Joint):
    """Training a fresh model on the union of all tasks so far, at every task."""

    name = "joint-scratch"
    Options = JointScratchOptions

    def __init__(self, model_config, options: dict[str, Any] | None = None):
        super().__init__(model_config, options)
        self.initial: dict[str, torch.Tensor] | None = None

    def before_task(self, ctx: TaskContext) -> None:
        if self.initial is None:
            self.initial = copy.deepcopy(ctx.model.state_dict())
            return
        ctx.model.load_state_dict(self.initial)
        ctx.optimiser.state.clear()  # Adam's moments belong to the old fit

    def training_windows(self, ctx: TaskContext) -> Windows:
        union = super().training_windows(ctx)
        if not self.options.final_only:
            return union
        if ctx.tasks is None:
            raise InputError("joint-scratch.final_only needs a curriculum of known length")
        return union if ctx.index == ctx.tasks - 1 else union.subset(np.arange(0))

    def state_dict(self, model: torch.nn.Module) -> dict[str, Any]:
        return {"initial": self.initial}

    def load_state_dict(self, state: dict[str, Any], model: torch.nn.Module) -> None:
        self.initial = state["initial"]
