"""Online EWC (Kirkpatrick et al. 2017; Schwarz et al. 2018): a Fisher-weighted pull to old weights.

After each task the diagonal Fisher of the loss is estimated from squared gradients over the
task's batches and folded into a running Fisher (``gamma`` decays the old one); the penalty
``lambda/2 * sum F (theta - theta*)^2`` then anchors later training.
Hooks: ``before_backward``, ``after_task``. Example: ``--methods ewc``
"""

from dataclasses import dataclass
from typing import Any

import torch

from c2inet.batch import batches
from c2inet.device import model_device
from c2inet.methods.base import Method, TaskContext
from c2inet.options import Tunable, require


@dataclass(frozen=True)
class EWCOptions:
    strength: float = 100.0  # lambda
    gamma: float = 1.0  # decay of the running Fisher (1: plain sum over tasks)
    fisher_batch_scenes: int = 16  # scenes per batch of the Fisher estimate

    def __post_init__(self):
        require(self, 0, "strength")
        require(self, 0, "gamma", high=1)
        require(self, 1, "fisher_batch_scenes")


class EWC(Method):
    """Online elastic weight consolidation."""

    name = "ewc"
    # down to 0.01: tuned at batch 64 it chose 1.3, at the old floor of 1 (docs/benchmark.md)
    search_space = {"strength": Tunable(0.01, 1e4, log=True)}
    Options = EWCOptions
    inert = {"strength": 0.0}

    def __init__(self, model_config, options: dict[str, Any] | None = None):
        super().__init__(model_config, options)
        self.fisher: dict[str, torch.Tensor] = {}
        self.anchor: dict[str, torch.Tensor] = {}

    def penalty(self, model: torch.nn.Module) -> torch.Tensor:
        total = torch.zeros((), device=model_device(model))
        for name, p in model.named_parameters():
            if name in self.fisher:
                total = total + (self.fisher[name] * (p - self.anchor[name]) ** 2).sum()
        return 0.5 * self.options.strength * total

    def before_backward(self, ctx: TaskContext) -> None:
        if self.fisher:
            ctx.add_loss("penalty", self.penalty(ctx.model))

    def after_task(self, ctx: TaskContext) -> None:
        model = ctx.model
        fisher = {n: torch.zeros_like(p) for n, p in model.named_parameters()}
        count = 0
        for batch in batches(ctx.train, self.options.fisher_batch_scenes, ctx.rng, ctx.device):
            model.zero_grad()
            model.loss(batch).loss.backward()
            for n, p in model.named_parameters():
                if p.grad is not None:
                    fisher[n] += p.grad.detach() ** 2
            count += 1
        model.zero_grad()
        for n in fisher:
            fisher[n] /= max(count, 1)
            self.fisher[n] = self.options.gamma * self.fisher.get(n, 0) + fisher[n]
        self.anchor = {n: p.detach().clone() for n, p in model.named_parameters()}

    def state_dict(self, model: torch.nn.Module) -> dict[str, Any]:
        return {"fisher": dict(self.fisher), "anchor": dict(self.anchor)}

    def load_state_dict(self, state: dict[str, Any], model: torch.nn.Module) -> None:
        self.fisher, self.anchor = dict(state["fisher"]), dict(state["anchor"])
