"""MoG (the paper's baseline, from BooVAE's ``vae/model/mog.py``): a mixture-of-Gaussians prior
over C that grows by a fixed number of learnable components per task.

C2INet's network, with the prior queue replaced by ``per_task`` learnable Gaussians trained with
the model through the KL of C; after each task they are frozen and appended to the prior, and the
next task learns new ones starting from where they were. Weights are uniform over every
component. The difference from C2INet is the prior's update rule alone: no boosting, no weight
fit, no pruning, no anchors, and no free bits (the prior learns through KL_C). Hook:
``after_task``. Example: ``--methods mog``
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import torch

from c2inet.methods.base import Method, TaskContext
from c2inet.model import C2INetModel
from c2inet.model_config import LATENT_SPACE
from c2inet.options import require
from c2inet.prior import LearnablePrior


@dataclass(frozen=True)
class MoGOptions:
    per_task: int = 5  # learnable Gaussians added by every task

    def __post_init__(self):
        require(self, 1, "per_task")


class MoG(Method):
    """C2INet's network with a mixture prior of frozen per-task learnt Gaussians."""

    name = "mog"
    search_space = LATENT_SPACE
    Options = MoGOptions

    def build_model(self) -> torch.nn.Module:
        prior = LearnablePrior(self.model_config.c_dim, self.options.per_task, learn_weights=False)
        # its prior learns through KL_C alone: free bits would leave it without a gradient
        config = dataclasses.replace(self.model_config, free_bits_c=0.0)
        return C2INetModel(config, prior=prior)

    def after_task(self, ctx: TaskContext) -> None:
        ctx.model.queue.freeze(next_owner=ctx.index + 1)

    def memory_floats(self, model: torch.nn.Module) -> int:
        """The frozen Gaussians of the finished tasks: kept in the model's state, but memory
        that grows with every task, as C2INet's queue does."""
        frozen = model.queue.frozen
        return frozen.means.numel() + frozen.logvars.numel() + frozen.weights.numel()
