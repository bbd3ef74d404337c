"""The one option builder: strict types, and ranges held whichever way an option is built."""

import math

import pytest

from c2inet.errors import InputError
from c2inet.methods.base import discover, get_method
from c2inet.model_config import ModelConfig
from c2inet.options import build
from c2inet.prior import QueueConfig
from c2inet.trainer import TrainConfig


@pytest.mark.parametrize(
    "cls, values, message",
    [
        (TrainConfig, {"lr": -1.0}, "lr=-1 is out of range (0"),
        (TrainConfig, {"lr": 0.0}, "lr=0 is out of range (0"),
        (TrainConfig, {"batch_scenes": 0}, "batch_scenes=0 is out of range [1"),
        (TrainConfig, {"epochs": 1.5}, "must be an integer"),
        (TrainConfig, {"epochs": 1e400}, "must be an integer"),
        (TrainConfig, {"lr": math.nan}, "must be finite"),
        (TrainConfig, {"k": True}, "must be an integer"),
        (ModelConfig, {"z_dim": -2}, "z_dim=-2 is out of range [1"),
        (ModelConfig, {"likelihood_std": 0.0}, "likelihood_std=0 is out of range (0"),
        (ModelConfig, {"n_mc": 0}, "n_mc=0 is out of range [1"),
        (QueueConfig, {"capacity": 0}, "capacity=0 is out of range [1"),
        (QueueConfig, {"fit_samples": 0}, "fit_samples=0"),
    ],
)
def test_bad_types_and_ranges_are_one_clear_error(cls, values, message):
    with pytest.raises(InputError, match=message.replace("(", r"\(").replace("[", r"\[")):
        build(cls, values, "where")


def test_ranges_hold_for_configurations_built_in_python_too():
    with pytest.raises(InputError, match="lr"):
        TrainConfig(lr=-1.0)
    with pytest.raises(InputError, match="capacity"):
        QueueConfig(capacity=0)


@pytest.mark.parametrize(
    "name, options",
    [
        ("c2inet-online", {"interval": 0}),
        ("c2inet-online", {"samples": 0}),
        ("ewc", {"gamma": 2.0}),
        ("ewc", {"strength": -1.0}),
        ("coresets", {"per_task": -1}),
        ("agem", {"memory_batch": 0}),
        ("derpp", {"buffer": 0}),
        ("derpp", {"replay_loss": "mse"}),
        ("lwf", {"strength": -0.1}),
        ("si", {"damping": 0.0}),
        ("invariant", {"environments": 1}),
        ("invariant", {"risk": "dro"}),
        ("mog", {"per_task": 0}),
        ("gcrl", {"components": 0}),
        ("pecnet", {"latent": 0}),
        ("coresets", {"per_task": 1.5}),
    ],
)
def test_method_options_are_range_checked(name, options):
    with pytest.raises(InputError, match=name):
        get_method(name)(ModelConfig(), options)


def test_every_method_builds_with_its_defaults():
    for cls in discover().values():
        cls(ModelConfig())
