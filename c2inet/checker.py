"""The method checker (as Gymnasium's ``check_env``): runs a method through a small curriculum of
arcs and raises :class:`MethodCheckError` naming the first broken promise.

It checks what every method owes the trainer: a documented contract, finite and consistent
metrics, the same numbers for the same seed, a resume after any task equal to an uninterrupted
run (all the method keeps goes through ``state_dict``), results up to a task that never depend on
a later task's data, every tensor made on the model's device (:class:`DeviceAudit`), and, for
methods that name the options switching their mechanism off (``Method.inert``), that switching
it off changes the numbers: a mechanism that is live.

    from c2inet.checker import check_method
    check_method(get_method("lwf"))
"""

from __future__ import annotations

import dataclasses
import sys
import tempfile
from pathlib import Path
from typing import Any

import numpy as np
import torch
from torch.overrides import _get_current_function_mode_stack
from torch.utils._device import DeviceContext

from c2inet.data import Windows
from c2inet.methods.base import Method
from c2inet.model_config import ModelConfig
from c2inet.trainer import TRAIN_SPACE, ContinualTrainer, Result, Task, TrainConfig

HOOKS = (
    "before_task",
    "training_windows",
    "step_loss",
    "before_backward",
    "after_backward",
    "after_step",
    "after_epoch",
    "after_task",
)
CHECK_CONFIG = TrainConfig(epochs=2, k=3, k_train=2, diagnostics=False)
# the tensor factories that take a device; ``*_like`` and ``Tensor.new_*`` follow their input
FACTORIES = ("zeros", "ones", "empty", "full", "arange", "linspace", "eye", "tensor", "as_tensor")
FACTORIES += ("rand", "randn", "randint", "randperm")


class DeviceAudit:
    """Notes every tensor factory called from code under ``roots`` without a ``device`` (and
    outside a ``with torch.device(...)`` block, which names one): such a tensor lands on the
    default device (the CPU) whatever the model's, and a run on a GPU fails or copies. Works on
    a CPU-only machine, by wrapping the factories while it is entered; only calls from
    ``roots`` count (torch's own are not the learner's to fix).

        with DeviceAudit([Path(c2inet.__file__).parent]) as audit:
            ...
        audit.found  # {".../c2inet/model.py:140", ...}
    """

    def __init__(self, roots: list[Path]):
        self.roots = tuple(str(r) for r in roots)
        self.found: set[str] = set()
        self._originals = {name: getattr(torch, name) for name in FACTORIES}

    def __enter__(self) -> DeviceAudit:
        for name, original in self._originals.items():
            setattr(torch, name, self._audited(original))
        return self

    def __exit__(self, *exc) -> None:
        for name, original in self._originals.items():
            setattr(torch, name, original)

    def _audited(self, factory):
        def audited(*args, **kwargs):
            if kwargs.get("device") is None and not _in_device_block():
                caller = sys._getframe(1)  # the Python line that called the factory
                path = caller.f_code.co_filename
                if path.startswith(self.roots):
                    self.found.add(f"{path}:{caller.f_lineno}")
            return factory(*args, **kwargs)

        return audited


def _in_device_block() -> bool:
    return any(isinstance(m, DeviceContext) for m in _get_current_function_mode_stack())


class MethodCheckError(AssertionError):
    """A method broke its contract; the message says which part and how."""


def turners(turn: float, scenes: int, seed: int) -> Windows:
    """3-agent scenes on arcs turning ``turn`` rad per frame: constant velocity cannot follow."""
    rng = np.random.default_rng(seed)
    agents = 3 * scenes
    heading = rng.uniform(-np.pi, np.pi, (agents, 1)) + turn * np.arange(20)
    steps = 0.4 * np.stack([np.cos(heading), np.sin(heading)], -1)
    steps += rng.normal(0, 0.02, steps.shape)
    positions = rng.uniform(-10, 10, (agents, 1, 2)) + np.cumsum(steps, axis=1)
    return Windows(positions.astype(np.float32), np.arange(0, agents + 1, 3))


def turning_tasks(turns=(0.1, 0.2), train=8, seed=0) -> list[Task]:
    """One task per turn rate, with ``train`` training scenes, 2 validation and 3 test scenes."""
    return [
        Task(
            f"turn_{t}",
            *(turners(t, n, 10 * i + s + 100 * seed) for s, n in enumerate((train, 2, 3))),
            t,
        )
        for i, t in enumerate(turns)
    ]


def _fail(cls: type[Method], what: str) -> None:
    raise MethodCheckError(f"method {cls.__name__} ({getattr(cls, 'name', '?')}): {what}")


def _run(
    cls: type[Method],
    tasks: list[Task],
    options: dict[str, Any] | None = None,
    folder: Path | None = None,
    resume: bool = False,
    config: TrainConfig = CHECK_CONFIG,
) -> tuple[Result, list[tuple]]:
    """A run of the method and the events its observers received."""
    events: list[tuple] = []

    def observe(event: str, data: dict[str, Any]) -> None:
        key = data["task"] if event == "task_end" else (data["task"], data["epoch"])
        events.append((event, key, data.get("row") or data.get("nll")))

    method = cls(ModelConfig(), options)
    trainer = ContinualTrainer(method, tasks, config, folder, [observe])
    return trainer.run(resume=resume), events


def _same(a: Result, b: Result, rows: slice = slice(None)) -> bool:
    return all(
        np.array_equal(a.matrices[m][rows], b.matrices[m][rows], equal_nan=True) for m in a.matrices
    )


def check_contract(cls: type[Method]) -> None:
    """Registered name, docstrings, a one-file module naming its hooks, typed options."""
    if not isinstance(getattr(cls, "name", None), str) or not cls.__doc__:
        _fail(cls, "needs a name and a class docstring")
    doc = sys.modules[cls.__module__].__doc__ or ""
    if "Example" not in doc:
        _fail(cls, "its module docstring needs an Example line (Mammoth-style)")
    for hook in HOOKS:
        owner = next(c for c in cls.__mro__ if hook in vars(c))
        if owner is not Method and hook not in (sys.modules[owner.__module__].__doc__ or ""):
            _fail(cls, f"overrides the hook {hook!r} but its module docstring does not name it")
    if not dataclasses.is_dataclass(cls.Options) or not cls.Options.__dataclass_params__.frozen:
        _fail(cls, "Options must be a frozen dataclass")
    check_search_space(cls)


def check_search_space(cls: type[Method]) -> None:
    """Every searched option exists (the method's own, or ``model.KEY``/``train.KEY``) and its
    default lies inside the searched range, so the default is one of the tuner's candidates."""
    if cls.search_space and not cls.trains:
        _fail(cls, "declares a search space but does not train")
    for key, space in {**cls.search_space, **(TRAIN_SPACE if cls.trains else {})}.items():
        scope, _, name = key.rpartition(".")
        owner = {"": cls.Options, "model": ModelConfig, "train": TrainConfig}.get(scope)
        fields = {} if owner is None else {f.name: f for f in dataclasses.fields(owner)}
        if name not in fields:
            _fail(cls, f"searches {key!r}, which is no option of it")
        if not space.holds(fields[name].default):
            _fail(cls, f"the default of {key!r} lies outside its searched range")


def check_metrics(cls: type[Method], result: Result) -> None:
    n = len(result.tasks)
    for metric, matrix in result.matrices.items():
        if matrix.shape != (n, n) or not np.isfinite(matrix).all():
            _fail(cls, f"matrix {metric!r} is not a finite {n}x{n} matrix")
    m = result.matrices
    if np.any(m["ade"] > m["ade_draw"] + 1e-9) or np.any(m["ade_agent"] > m["ade"] + 1e-9):
        _fail(cls, "best of K is worse than its first sample, or the joint minimum beats per agent")


def check_determinism_and_resume(
    cls: type[Method], tasks: list[Task], whole: Result, events: list, config=CHECK_CONFIG
) -> None:
    """A second run with the same seed gives the same numbers and events; resuming it after
    each finished task (from its own checkpoints) gives them again."""
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        again, again_events = _run(cls, tasks, folder=folder, config=config)
        if not _same(again, whole) or again.history != whole.history or again_events != events:
            _fail(cls, "two runs with the same seed differ")
        for finished in range(1, len(tasks)):
            for later in range(finished, len(tasks)):
                (folder / f"task_{later:02d}.pt").unlink(missing_ok=True)
            resumed, resumed_events = _run(cls, tasks, folder=folder, resume=True, config=config)
            if not _same(resumed, whole) or resumed.history != whole.history:
                _fail(cls, f"a run resumed after task {finished - 1} gives other numbers")
            if resumed.summaries != whole.summaries or resumed_events != events:
                _fail(cls, f"a run resumed after task {finished - 1} reports other events")


def check_no_peeking(cls: type[Method], tasks: list[Task], whole: Result, config=CHECK_CONFIG):
    """Results after task i never depend on the training data of a later task."""
    last = tasks[-1]
    other = turners(float(last.value) + 0.15, len(last.train), seed=999)
    changed = [*tasks[:-1], dataclasses.replace(last, train=other, val=other.subset([0, 1]))]
    result, _ = _run(cls, changed, config=config)
    if not _same(result, whole, slice(None, -1)):
        _fail(cls, "results before the last task changed with the last task's training data")
    if cls.trains and _same(result, whole):
        _fail(cls, "the last task's training data changed nothing: is it trained on?")


def check_devices(cls: type[Method], audit: DeviceAudit) -> None:
    """Every tensor the run made was made on the model's device (see :class:`DeviceAudit`)."""
    if audit.found:
        _fail(cls, f"makes tensors without naming a device at {', '.join(sorted(audit.found))}")


def check_live(cls: type[Method], tasks: list[Task], whole: Result, config=CHECK_CONFIG):
    """Switching each of the method's mechanisms off (``cls.inert``: a switch set, or a list of
    them) must change the numbers."""
    if cls.inert is None:
        return
    for switches in cls.inert if isinstance(cls.inert, list) else [cls.inert]:
        result, _ = _run(cls, tasks, switches, config=config)
        if _same(result, whole):
            _fail(cls, f"its mechanism is inert: options {switches} change nothing")


def check_method(cls: type[Method], device: str = "cpu") -> None:
    """Every check above, on three tasks of arcs turning 0.1, 0.2 and 0.3 rad per frame, with
    the models on ``device``."""
    check_contract(cls)
    tasks = turning_tasks(turns=(0.1, 0.2, 0.3))
    config = dataclasses.replace(CHECK_CONFIG, device=device)
    roots = [Path(__file__).parent, Path(sys.modules[cls.__module__].__file__).parent]
    with DeviceAudit(roots) as audit:
        whole, events = _run(cls, tasks, config=config)
    check_devices(cls, audit)
    check_metrics(cls, whole)
    check_determinism_and_resume(cls, tasks, whole, events, config)
    check_no_peeking(cls, tasks, whole, config)
    check_live(cls, tasks, whole, config)
