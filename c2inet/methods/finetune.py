"""Fine-tuning: train on each task in turn with no protection against forgetting (no hooks).

Example: ``python -m sim.run --scenario crowd_noise_0.1..0.6 --methods finetune``
"""

from c2inet.methods.base import Method


class Finetune(Method):
    """Sequential training with no protection against forgetting."""

    name = "finetune"
