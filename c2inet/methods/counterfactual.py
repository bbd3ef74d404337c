"""Counterfactual (Chen et al., ICCV 2021, "Human Trajectory Prediction via Counterfactual
Analysis"): remove the bias the environment puts into the prediction by subtracting what the
model would predict from a counterfactual, blank past.

The encoder reads the factual past and a blank one (every agent standing still at its last
observed position); the decoder is conditioned on their difference, as the ``counter`` switch of
Liu et al.'s code subtracts the counterfactual hidden state from the factual one, in training
and at test alike. What is left is the part of the prediction the observed motion causes.
Trained in sequence with no protection against forgetting, as in the paper's tables.
No hooks. Example: ``--methods counterfactual``
"""

from __future__ import annotations

import torch

from c2inet.batch import Batch
from c2inet.methods.base import Method
from c2inet.model import Predictor


class CounterfactualPredictor(Predictor):
    """The plain predictor, its context the factual minus the counterfactual encoding."""

    def context(self, batch: Batch) -> torch.Tensor:
        factual = self.backbone.encode(batch.obs_rel / batch.scale, batch)
        blank = self.backbone.encode(torch.zeros_like(batch.obs_rel), batch)
        return factual - blank


class Counterfactual(Method):
    """Counterfactual analysis: factual minus blank-past encoding."""

    name = "counterfactual"

    def build_model(self) -> torch.nn.Module:
        return CounterfactualPredictor(self.model_config)
