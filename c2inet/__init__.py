"""The learner, a library on its own: input type, backbones, C2INet, continual methods, metrics.

The names a user needs are here::

    from c2inet import ContinualTrainer, ModelConfig, Task, TrainConfig, Windows, get_method
"""

from c2inet.data import Windows
from c2inet.methods.base import get_method
from c2inet.model import ModelConfig
from c2inet.report import summarise
from c2inet.trainer import ContinualTrainer, Task, TrainConfig

__all__ = [
    "ContinualTrainer",
    "ModelConfig",
    "Task",
    "TrainConfig",
    "Windows",
    "get_method",
    "summarise",
]
