"""SI (Zenke et al., ICML 2017, "Continual Learning Through Synaptic Intelligence"): a quadratic
pull to old weights, each weighted by how much it moved the loss along its training path.

During a task every step adds -g * (its change) to each weight's path integral (the gradient
from the backward pass, the change from the optimiser step); after the task the integral divided
by the squared total change (plus ``damping``) joins the running importance, clamped at zero
(a negative importance would reward drift), and the weights become the new anchor.
Hooks: ``before_task``, ``before_backward``, ``after_backward``, ``after_step``, ``after_task``.
Example: ``--methods si``
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import torch

from c2inet.methods.base import Method, TaskContext
from c2inet.options import Tunable, require


@dataclass(frozen=True)
class SIOptions:
    strength: float = 1.0  # c
    damping: float = 0.1  # xi

    def __post_init__(self):
        require(self, 0, "strength")
        require(self, 0, "damping", open_low=True)


def weights(model: torch.nn.Module) -> dict[str, torch.Tensor]:
    return {n: p.detach().clone() for n, p in model.named_parameters()}


class SI(Method):
    """Synaptic intelligence: online path-integral importance of every weight."""

    name = "si"
    search_space = {"strength": Tunable(0.01, 100.0, log=True)}
    Options = SIOptions
    inert = {"strength": 0.0}

    def __init__(self, model_config, options: dict[str, Any] | None = None):
        super().__init__(model_config, options)
        self.importance: dict[str, torch.Tensor] = {}
        self.anchor: dict[str, torch.Tensor] = {}
        self.path: dict[str, torch.Tensor] = {}
        self.start: dict[str, torch.Tensor] = {}
        self.previous: dict[str, torch.Tensor] = {}
        self.grads: dict[str, torch.Tensor] = {}

    def before_task(self, ctx: TaskContext) -> None:
        self.start = weights(ctx.model)
        self.previous = weights(ctx.model)
        self.path = {n: torch.zeros_like(p) for n, p in self.start.items()}

    def before_backward(self, ctx: TaskContext) -> None:
        if self.importance:
            total = sum(
                (self.importance[n] * (p - self.anchor[n]) ** 2).sum()
                for n, p in ctx.model.named_parameters()
            )
            ctx.add_loss("penalty", self.options.strength * total)

    def after_backward(self, ctx: TaskContext) -> None:
        self.grads = {
            n: p.grad.detach().clone()
            for n, p in ctx.model.named_parameters()
            if p.grad is not None
        }

    def after_step(self, ctx: TaskContext) -> None:
        for n, p in ctx.model.named_parameters():
            now = p.detach()
            if n in self.grads:
                self.path[n] -= self.grads[n] * (now - self.previous[n])
            self.previous[n] = now.clone()

    def after_task(self, ctx: TaskContext) -> None:
        for n, p in ctx.model.named_parameters():
            moved = (p.detach() - self.start[n]) ** 2
            gained = (self.path[n] / (moved + self.options.damping)).clamp_min(0)
            self.importance[n] = self.importance.get(n, 0) + gained
        self.anchor = weights(ctx.model)

    def state_dict(self, model: torch.nn.Module) -> dict[str, Any]:
        return {"importance": dict(self.importance), "anchor": dict(self.anchor)}

    def load_state_dict(self, state: dict[str, Any], model: torch.nn.Module) -> None:
        self.importance, self.anchor = dict(state["importance"]), dict(state["anchor"])
