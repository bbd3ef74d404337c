"""Adaptive: the modular style adapter of Liu et al. (CVPR 2022, "Towards Robust and Adaptive
Motion Forecasting: A Causal Representation Perspective"), the paper's ADAPTIVE row.

Why this paper: the paper's baselines INVARIANT and ADAPTIVE sit side by side and come from the
same code base ([CM], its ``spurious/`` and ``style/`` folders), and Liu et al.'s title is
"Robust and Adaptive"; the other candidate the appendix cites (meta-learnt adaptation, Ivanovic
et al. 2023) has no released code the paper could have run. A style encoder reads each scene's
pooled context and modulates the decoder's condition (FiLM: scale and shift, starting at the
identity). The first task trains everything; each later task adapts the style modulator alone,
the rest frozen, as Liu et al. adapt to a new domain. Hook: ``before_task``.
Example: ``--methods adaptive``
"""

from __future__ import annotations

import torch
from torch import nn

from c2inet.batch import Batch
from c2inet.methods.base import Method, TaskContext
from c2inet.model import Predictor


class StylePredictor(Predictor):
    """The plain predictor with a per-scene style modulating the decoder's condition."""

    def __init__(self, config):
        super().__init__(config)
        width = self.backbone.context_dim
        cond_dim = width + config.latent_dim
        self.style = nn.Sequential(nn.Linear(width, 32), nn.ReLU(), nn.Linear(32, 2 * cond_dim))
        nn.init.zeros_(self.style[-1].weight)
        nn.init.zeros_(self.style[-1].bias)
        self.width = width

    def decode(self, batch: Batch, cond: torch.Tensor) -> torch.Tensor:
        """The condition (S, N, context + noise) modulated by its scene's style."""
        context = cond[0, :, : self.width]  # the same in every sample
        scale, shift = self.style(batch.pool(context)[batch.scene_of]).chunk(2, -1)
        return super().decode(batch, cond * (1 + scale) + shift)


class Adaptive(Method):
    """Train everything on the first task, then adapt the style modulator alone."""

    name = "adaptive"

    def build_model(self) -> torch.nn.Module:
        return StylePredictor(self.model_config)

    def before_task(self, ctx: TaskContext) -> None:
        for name, parameter in ctx.model.named_parameters():
            parameter.requires_grad_(ctx.index == 0 or name.startswith("style."))
