"""The method contract: a small class adding behaviour to the one trainer through hooks.

Hooks, in the order the trainer calls them (Avalanche-style): ``before_task``,
``training_windows``, ``extra_loss`` (every step), ``after_epoch``, ``after_task``. A method
says in its docstring which hooks it uses. What it keeps between tasks goes through
``state_dict`` / ``load_state_dict``, so a run resumes exactly. Methods register by ``name``.
"""

from __future__ import annotations

import dataclasses
import importlib
import pkgutil
from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np
import torch

from c2inet.data import Windows
from c2inet.errors import did_you_mean
from c2inet.model import ModelConfig, Predictor

METHODS: dict[str, type[Method]] = {}


@dataclass
class TaskContext:
    """What a hook may look at: the current task's data, the model and the optimiser."""

    index: int  # 0-based position of the task in the curriculum
    name: str
    train: Windows
    model: torch.nn.Module
    optimiser: torch.optim.Optimizer | None
    rng: np.random.Generator
    seen_train: list[Windows] = field(default_factory=list)  # earlier tasks (joint only)


@dataclass(frozen=True)
class NoOptions:
    """Methods without options."""


def build_options(cls: type, values: dict[str, Any]):
    """``cls(**values)`` with every key checked and values converted to the field's type."""
    fields = {f.name: f for f in dataclasses.fields(cls)}
    out = {}
    for key, value in values.items():
        if key not in fields:
            known = ", ".join(fields) or "none"
            raise ValueError(
                f"unknown option {key!r}{did_you_mean(key, fields)} (options: {known})"
            )
        kind = type(getattr(cls(), key))
        if kind is bool and not isinstance(value, bool):
            raise ValueError(f"option {key!r} must be true or false, got {value!r}")
        try:
            out[key] = kind(value)
        except (TypeError, ValueError):
            raise ValueError(f"option {key!r} must be {kind.__name__}, got {value!r}") from None
    return cls(**out)


class Method:
    """Plain sequential training; subclasses override the hooks they need."""

    name: ClassVar[str]
    trains: ClassVar[bool] = True
    sees_old_tasks: ClassVar[bool] = False  # True only for the joint upper reference
    Options: ClassVar[type] = NoOptions  # a frozen dataclass of the method's options

    def __init_subclass__(cls, **kwargs):
        super().__init_subclass__(**kwargs)
        METHODS[cls.name] = cls

    def __init__(self, model_config: ModelConfig, options: dict[str, Any] | None = None):
        self.model_config = model_config
        self.options = build_options(self.Options, options or {})

    def build_model(self) -> torch.nn.Module:
        return Predictor(self.model_config)

    def before_task(self, ctx: TaskContext) -> None:
        pass

    def training_windows(self, ctx: TaskContext) -> Windows:
        return ctx.train

    def extra_loss(self, model: torch.nn.Module) -> torch.Tensor | None:
        """A penalty added to every training step's loss (None: nothing)."""
        return None

    def after_epoch(self, ctx: TaskContext, epoch: int) -> None:
        pass

    def after_task(self, ctx: TaskContext) -> None:
        pass

    def state_dict(self, model: torch.nn.Module) -> dict[str, Any]:
        """All the method keeps between tasks (tensors and plain values only), saved with each
        task checkpoint; with the model's own state it is what a resumed run continues from."""
        return {}

    def load_state_dict(self, state: dict[str, Any], model: torch.nn.Module) -> None:
        """Restore what :meth:`state_dict` returned, into this method and ``model``."""
        if state:
            raise ValueError(f"method {self.name!r} keeps no state, got {sorted(state)}")

    def summary(self) -> dict[str, Any]:
        """Extra per-task figures for the report (e.g. the queue size)."""
        return {}


def discover() -> dict[str, type[Method]]:
    """Every method: the modules of ``c2inet.methods`` register their classes on import."""
    import c2inet.methods

    for module in pkgutil.iter_modules(c2inet.methods.__path__):
        importlib.import_module(f"c2inet.methods.{module.name}")
    return METHODS


def get_method(name: str) -> type[Method]:
    discover()
    if name not in METHODS:
        hint = did_you_mean(name, METHODS)
        raise KeyError(f"unknown method {name!r}{hint} (known: {', '.join(sorted(METHODS))})")
    return METHODS[name]
