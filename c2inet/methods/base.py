"""The method contract: a small class adding behaviour to the one trainer through hooks.

Hooks, in the order the trainer calls them (Avalanche-style), each given the
:class:`TaskContext`: ``before_task``, ``training_windows``, then at every step ``step_loss``
(the batch's loss; a method that adds scenes of its own scores them in the same forward pass),
``before_backward`` (the batch, the model output and the loss are in the context; add penalties
with ``ctx.add_loss``), ``after_backward`` (the gradients are there: project them),
``after_step`` (the optimiser has moved the weights), then ``after_epoch`` and ``after_task``.
A method says in its docstring which hooks it uses. What it keeps between tasks goes through
``state_dict`` / ``load_state_dict``, so a run resumes exactly. Methods register by ``name`` and
are found by :func:`discover`; :mod:`c2inet.checker` checks each against the contract.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np
import torch

from c2inet.batch import Batch
from c2inet.data import Windows
from c2inet.device import model_device
from c2inet.model import LossOutput, Predictor
from c2inet.model_config import ModelConfig
from c2inet.options import Choice, Tunable, build
from c2inet.registry import Registry

PLUGINS = "c2inet.methods"  # the entry-point group through which other packages add methods
REGISTRY: Registry[type[Method]] = Registry(
    "method", "c2inet.methods", PLUGINS, lambda entry: _is_method(entry)
)
METHODS = REGISTRY.entries  # name -> class, filled as the method modules are imported


@dataclass
class TaskContext:
    """What a hook may look at: the current task's data, the model and the optimiser, and during
    a training step the batch, the model's output and the loss (as Avalanche's strategy)."""

    index: int  # 0-based position of the task in the curriculum
    name: str
    train: Windows
    model: torch.nn.Module
    optimiser: torch.optim.Optimizer | None
    rng: np.random.Generator
    seen_train: list[Windows] = field(default_factory=list)  # earlier tasks (joint only)
    batch: Batch | None = None  # the step's batch
    output: torch.Tensor | None = None  # its predicted normalised displacements (12, S, N, 2)
    loss: torch.Tensor | None = None  # the step's loss so far
    parts: dict[str, float] = field(default_factory=dict)  # the loss's parts, for the logs
    tasks: int | None = None  # the curriculum's length, where it is known (not in a stream)

    @property
    def device(self) -> torch.device:
        """The model's device: every tensor a hook makes belongs there."""
        return model_device(self.model)

    def add_loss(self, name: str, value: torch.Tensor) -> None:
        """Add a penalty to the step's loss, logged as ``name`` (kept on the device: the
        trainer reads the parts once an epoch, not at every step)."""
        self.loss = self.loss + value
        self.parts[name] = value.detach()


TASK_HOOKS = ("before_task", "after_task")


@dataclass(frozen=True)
class NoOptions:
    """Methods without options."""


class Method:
    """Plain sequential training; subclasses override the hooks they need."""

    name: ClassVar[str]
    trains: ClassVar[bool] = True
    sees_old_tasks: ClassVar[bool] = False  # True only for the joint upper reference
    Options: ClassVar[type] = NoOptions  # a frozen dataclass of the method's options
    # options that switch the method's mechanism off, changing nothing else (no other use of
    # the random streams): the checker requires them to change the numbers. A method with
    # several mechanisms declares a list, one switch set per mechanism, each checked alone
    inert: ClassVar[dict[str, Any] | list[dict[str, Any]] | None] = None
    # what a tuner searches beside the learning rate (``TRAIN_SPACE``): the method's own
    # options by name, shared scopes as ``model.KEY``; every method gets the same trials
    search_space: ClassVar[dict[str, Tunable | Choice]] = {}

    def __init_subclass__(cls, **kwargs):
        """A subclass defined in ``c2inet.methods`` registers under its own name; one defined
        elsewhere never registers itself (``Registry.enrol``): a plugin comes in through its
        entry point, and cannot replace a built-in."""
        super().__init_subclass__(**kwargs)
        REGISTRY.enrol(cls)

    def __init__(self, model_config: ModelConfig, options: dict[str, Any] | None = None):
        self.model_config = model_config
        self.options = build(self.Options, options or {}, self.name)

    def build_model(self) -> torch.nn.Module:
        return Predictor(self.model_config)

    @classmethod
    def needs_boundaries(cls) -> bool:
        """Whether the method's mechanism lives in the task hooks (``before_task``,
        ``after_task``), so that a stream without task boundaries leaves it idle."""
        return any(getattr(cls, hook) is not getattr(Method, hook) for hook in TASK_HOOKS)

    def before_task(self, ctx: TaskContext) -> None:
        """Before the task's first epoch."""

    def training_windows(self, ctx: TaskContext) -> Windows:
        return ctx.train

    def step_loss(self, ctx: TaskContext, batch: Batch, k_train: int) -> LossOutput:
        """Every step, the loss of ``batch`` before penalties; it becomes ``ctx.loss``,
        ``ctx.parts`` and ``ctx.output``. Override to score scenes of the method's own in the
        same forward pass (DER++'s replay)."""
        return ctx.model.loss(batch, k_train)

    def before_backward(self, ctx: TaskContext) -> None:
        """Every step, before the backward pass: add penalties with ``ctx.add_loss``."""

    def after_backward(self, ctx: TaskContext) -> None:
        """Every step, after the backward pass: the gradients may be changed here."""

    def after_step(self, ctx: TaskContext) -> None:
        """Every step, after the optimiser step."""

    def after_epoch(self, ctx: TaskContext, epoch: int) -> None:
        """After every epoch of the task (0-based ``epoch``)."""

    def after_task(self, ctx: TaskContext) -> None:
        """After the task's last epoch, before it is evaluated."""

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

    @classmethod
    def replay_options(cls, scenes: int, tasks: int) -> dict[str, Any]:
        """The options that give a replay method a memory of ``scenes`` scenes in all after
        ``tasks`` tasks (an equal budget for every replay method); none for the others."""
        return {}

    def memory_floats(self, model: torch.nn.Module) -> int:
        """How many floating-point numbers the method keeps between tasks besides the model
        (buffers, anchors, Fisher, old parameters, the queue): what :meth:`state_dict` holds."""
        return count_floats(self.state_dict(model))


def count_floats(value: Any) -> int:
    """The floating-point entries of tensors and arrays in nested dicts, lists and tuples."""
    if isinstance(value, dict):
        return sum(count_floats(v) for v in value.values())
    if isinstance(value, list | tuple):
        return sum(count_floats(v) for v in value)
    if isinstance(value, torch.Tensor) and value.is_floating_point():
        return value.numel()
    if isinstance(value, np.ndarray) and np.issubdtype(value.dtype, np.floating):
        return value.size
    return 0


def _is_method(entry: Any) -> str | None:
    """Why a plugin's entry point is not a method (None: it is one)."""
    if isinstance(entry, type) and issubclass(entry, Method):
        return None
    return f"{entry!r} is not a subclass of c2inet.methods.base.Method"


def discover() -> dict[str, type[Method]]:
    """Every method: the modules of ``c2inet.methods`` register their classes on import, and so
    do other packages' entry points of the group ``c2inet.methods`` (name = the method's name,
    value = its class, e.g. ``mine = "my_package.methods:Mine"``)."""
    return REGISTRY.discover()


def get_method(name: str) -> type[Method]:
    """The method called ``name`` (an :class:`~c2inet.registry.UnknownName` otherwise)."""
    return REGISTRY.get(name)
