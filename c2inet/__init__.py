"""The learner, a library on its own: input type, backbones, C2INet, continual methods, metrics.

The names a user needs are here:

    from c2inet import ContinualTrainer, ModelConfig, Task, TrainConfig, Windows, get_method
"""

from c2inet.lazy import lazy_exports

_HOMES = {
    "ContinualTrainer": "c2inet.trainer",
    "ModelConfig": "c2inet.model",
    "Task": "c2inet.trainer",
    "TrainConfig": "c2inet.trainer",
    "Windows": "c2inet.data",
    "get_method": "c2inet.methods.base",
    "summarise": "c2inet.report",
}
__all__ = sorted(_HOMES)

# imported on first use: a module that needs only ``c2inet.errors`` (the simulators'
# commands, their worker processes) does not pay torch's second of import
__getattr__ = lazy_exports(__name__, _HOMES)
