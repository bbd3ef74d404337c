"""Constant velocity: repeat the last observed displacement. No training, no hooks.

The floor every learner must beat. Example: ``--methods cv``
"""

import torch
from torch import nn

from c2inet.batch import Batch
from c2inet.methods.base import Method


class ConstantVelocity(nn.Module):
    """Repeats the last observed displacement: no training, the floor every learner must beat."""

    @torch.no_grad()
    def predict(self, batch: Batch, samples: int) -> torch.Tensor:
        steps = torch.arange(1, len(batch.fut) + 1, dtype=batch.obs.dtype, device=batch.obs.device)
        steps = steps[:, None, None]
        future = batch.obs[-1] + steps * batch.obs_rel[-1]
        return future.expand(samples, *future.shape)

    def evaluation_variants(self, task: int | None = None) -> dict[str, dict]:
        return {}


class ConstantVelocityMethod(Method):
    """The last observed displacement, repeated: the floor."""

    name = "cv"
    trains = False

    def build_model(self) -> torch.nn.Module:
        return ConstantVelocity()
