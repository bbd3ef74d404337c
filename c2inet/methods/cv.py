"""Constant velocity: repeat the last observed displacement. No training, no hooks.

The floor every learner must beat. Example: ``--methods cv``
"""

import torch

from c2inet.methods.base import Method
from c2inet.model import ConstantVelocity


class ConstantVelocityMethod(Method):
    """The last observed displacement, repeated: the floor."""

    name = "cv"
    trains = False

    def build_model(self) -> torch.nn.Module:
        return ConstantVelocity()
