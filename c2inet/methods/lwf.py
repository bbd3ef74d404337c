"""LwF (Li & Hoiem, ECCV 2016, "Learning without Forgetting"): hold the model's predictions on
the new task's scenes to those of the model as it was after the previous task.

For a regressor the "soft targets" are the old model's noise-free predictions (``point``), and
the distillation term is their squared error under the model's own Gaussian likelihood, so it
weighs like the task loss. No old data is kept; only the previous model.
Hooks: ``before_backward``, ``after_task``. Example: ``--methods lwf``
"""

from __future__ import annotations

import copy
from dataclasses import dataclass
from typing import Any

import torch

from c2inet.methods.base import Method, TaskContext
from c2inet.options import Tunable, require


@dataclass(frozen=True)
class LwFOptions:
    strength: float = 1.0  # weight of the distillation term

    def __post_init__(self):
        require(self, 0, "strength")


class LwF(Method):
    """Distillation from the previous task's model on the current scenes."""

    name = "lwf"
    search_space = {"strength": Tunable(1e-4, 100.0, log=True)}  # 0.02 chosen, floor was 0.01
    Options = LwFOptions
    inert = {"strength": 0.0}

    def __init__(self, model_config, options: dict[str, Any] | None = None):
        super().__init__(model_config, options)
        self.teacher: torch.nn.Module | None = None

    def before_backward(self, ctx: TaskContext) -> None:
        if self.teacher is None:
            return
        with torch.no_grad():
            target = self.teacher.point(ctx.batch)
        drift = ((ctx.model.point(ctx.batch) - target) ** 2).sum(dim=(0, 2))
        drift = ctx.batch.per_scene_mean(drift).mean() / (2 * self.model_config.likelihood_std**2)
        ctx.add_loss("distill", self.options.strength * drift)

    def _freeze(self, model: torch.nn.Module) -> None:
        self.teacher = model.eval().requires_grad_(False)

    def after_task(self, ctx: TaskContext) -> None:
        self._freeze(copy.deepcopy(ctx.model))

    def state_dict(self, model: torch.nn.Module) -> dict[str, Any]:
        return {"teacher": None if self.teacher is None else self.teacher.state_dict()}

    def load_state_dict(self, state: dict[str, Any], model: torch.nn.Module) -> None:
        self.teacher = None
        if state["teacher"] is not None:
            teacher = self.build_model()
            teacher.load_state_dict(state["teacher"])
            self._freeze(teacher)
