"""A-GEM (Chaudhry et al., ICLR 2019, "Efficient Lifelong Learning with A-GEM"): never let a
step increase the loss on an episodic memory of old scenes, to first order.

The memory is the coresets' (``per_task`` random scenes of every finished task), but it is not
trained on: after each backward pass the loss of ``memory_batch`` remembered scenes gives a
reference gradient, and when the step's gradient points against it (negative dot product) it is
projected onto the plane orthogonal to it. Hooks: ``before_task``, ``training_windows`` (the
task's own scenes, no replay), ``after_backward``, ``after_task``.
Example: ``--methods agem``
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import torch

from c2inet.batch import make_batch
from c2inet.data import Windows
from c2inet.methods.base import TaskContext
from c2inet.methods.coresets import CoresetOptions, Coresets
from c2inet.options import require


@dataclass(frozen=True)
class AGEMOptions(CoresetOptions):
    memory_batch: int = 16  # remembered scenes per reference gradient

    def __post_init__(self):
        super().__post_init__()
        require(self, 1, "memory_batch")


def gradient(parameters: list[torch.nn.Parameter]) -> torch.Tensor:
    """The parameters' gradients as one flat vector (zeros where a parameter has none)."""
    return torch.cat(
        [(torch.zeros_like(p) if p.grad is None else p.grad).flatten() for p in parameters]
    )


def project(step: torch.Tensor, reference: torch.Tensor) -> tuple[torch.Tensor, bool]:
    """``step`` projected orthogonally to ``reference`` when they conflict, and whether it was."""
    dot = step @ reference
    if dot >= 0:
        return step, False
    return step - dot / (reference @ reference).clamp_min(1e-12) * reference, True


class AGEM(Coresets):
    """Averaged gradient episodic memory: gradients projected away from old scenes' loss."""

    name = "agem"
    Options = AGEMOptions

    def __init__(self, model_config, options: dict[str, Any] | None = None):
        super().__init__(model_config, options)
        self.projected = 0  # steps of the current task whose gradient was projected

    def before_task(self, ctx: TaskContext) -> None:
        self.projected = 0

    def training_windows(self, ctx: TaskContext) -> Windows:
        return ctx.train

    def after_backward(self, ctx: TaskContext) -> None:
        if not self.buffer:
            return
        parameters = [p for p in ctx.model.parameters() if p.requires_grad]
        step = gradient(parameters)
        memory = Windows.concat(self.buffer)
        scenes = ctx.rng.choice(len(memory), min(self.options.memory_batch, len(memory)), False)
        ctx.model.zero_grad()
        ctx.model.loss(make_batch(memory, scenes, ctx.device), ctx.output.shape[1]).loss.backward()
        step, projected = project(step, gradient(parameters))
        self.projected += projected
        for p, g in zip(parameters, step.split([p.numel() for p in parameters]), strict=True):
            p.grad = g.view_as(p).clone()

    def summary(self) -> dict[str, Any]:
        return {**super().summary(), "projected_steps": self.projected}
