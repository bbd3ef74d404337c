"""Invariant (Liu et al., CVPR 2022, "Towards Robust and Adaptive Motion Forecasting: A Causal
Representation Perspective"): an IRMv1 or V-REx penalty that asks the risk to be the same in
every training environment.

Which environments, under a continual protocol? Only the current task's data is there, and one
task as one environment makes either penalty zero. So the environments are cut inside the task
from a nuisance that varies between its scenes: each scene's motion scale (its mean observed
step length), split at the task's quantiles into ``environments`` groups. IRMv1 penalises the
squared gradient of each environment's risk with respect to a dummy scale on the output
(Arjovsky et al. 2019); V-REx the variance of the risks (Krueger et al. 2021). Risks are the
step's variety loss per scene; the penalty is weighed against the loss as in Liu et al.'s
squared-error units. Hooks: ``before_task``, ``before_backward``. Example: ``--methods
invariant``
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import torch

from c2inet.batch import Batch, make_batch
from c2inet.methods.base import Method, TaskContext
from c2inet.options import Tunable, choose, require

RISKS = ("irm", "vrex")


@dataclass(frozen=True)
class InvariantOptions:
    risk: str = "irm"  # irm | vrex
    weight: float = 1.0  # the penalty's weight (Liu et al.'s ic_weight: 1, 3 or 5)
    environments: int = 2  # groups of scenes by motion scale

    def __post_init__(self):
        choose(self, "risk", RISKS)
        require(self, 0, "weight")
        require(self, 2, "environments", high=100)


def scene_scales(batch: Batch) -> torch.Tensor:
    """(B,) the motion scale of every scene of ``batch``."""
    return batch.pool(batch.scale)[:, 0]


class Invariant(Method):
    """An invariance penalty across environments of differing motion scale."""

    name = "invariant"
    search_space = {"weight": Tunable(0.01, 10.0, log=True)}
    Options = InvariantOptions
    inert = {"weight": 0.0}

    def __init__(self, model_config, options: dict[str, Any] | None = None):
        super().__init__(model_config, options)
        self.edges: torch.Tensor | None = None  # set by each task

    def before_task(self, ctx: TaskContext) -> None:
        scales = scene_scales(make_batch(ctx.train, device=ctx.device)).cpu().numpy()
        cuts = np.arange(1, self.options.environments) / self.options.environments
        self.edges = torch.as_tensor(
            np.quantile(scales, cuts), dtype=torch.float32, device=ctx.device
        )

    def risks(self, ctx: TaskContext, scale: torch.Tensor) -> list[torch.Tensor]:
        """The variety loss of each environment present in the batch, the output scaled."""
        batch = ctx.batch
        per_scene = batch.per_scene_mean(ctx.model.nll(batch, ctx.output * scale)).min(0).values
        env = torch.bucketize(scene_scales(batch), self.edges)
        return [per_scene[env == e].mean() for e in env.unique()]

    def before_backward(self, ctx: TaskContext) -> None:
        if self.options.risk == "irm":
            dummy = torch.ones((), requires_grad=True, device=ctx.device)
            grads = [
                torch.autograd.grad(r, dummy, create_graph=True)[0] for r in self.risks(ctx, dummy)
            ]
            penalty = torch.stack(grads).pow(2).sum()
        else:
            risks = torch.stack(self.risks(ctx, torch.ones((), device=ctx.device)))
            penalty = risks.var(unbiased=False)
        # Liu et al.'s risk is a squared error; ours is that over 2 sigma^2, so their
        # risk + weight * penalty is, in our units, loss + weight * 2 sigma^2 * penalty
        scale = 2 * self.model_config.likelihood_std**2
        ctx.add_loss("penalty", self.options.weight * scale * penalty)
