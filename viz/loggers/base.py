"""The logger skeleton and registry, and what every logger shares: the numbers of a trainer
event at their global step, and a configuration as flat parameters.

A logger is a :class:`Logger` subclass in a module of ``viz.loggers`` (or another package's entry
point of the group ``viz.loggers``), found by :data:`REGISTRY`: one file adds one. It is made
once per job, called with every trainer event and closed when the job ends; a resumed job
replays its finished tasks' events, so each logger starts its output afresh.
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

from c2inet.errors import InputError, did_you_mean, one_line
from c2inet.registry import Registry

ROW_METRICS = ("ade", "fde", "ade_k1", "fde_k1", "ade_draw", "fde_draw")


class Logger:
    """One job's logger: ``name`` (``--logger NAME``), ``title`` (one line for ``--list
    loggers``), ``value``: what ``NAME=VALUE`` means (empty: it takes none), ``values``: the
    values it accepts (empty: any text)."""

    name: str = ""
    title: str = ""
    value: str = ""
    values: tuple[str, ...] = ()

    def __init__(self, folder: Path, epochs: int, tasks: list[str], **options: Any):
        raise NotImplementedError

    def __call__(self, event: str, data: dict[str, Any]) -> None:
        raise NotImplementedError

    def close(self) -> None:
        """End the job's output (the default: nothing to end)."""

    @classmethod
    def prepare(cls, group: Path, value: str | None) -> None:
        """What the jobs of ``group`` (a run's folder, or a sweep's or a benchmark's, whose runs
        compare side by side) share, made once before they start (the default: nothing)."""

    @classmethod
    def log_outputs(cls, run_folder: Path, group: Path, value: str | None, files: list[Path]):
        """The run's report, figures and recording, once written (the default: nothing)."""


def _is_logger(entry: Any) -> str | None:
    ok = isinstance(entry, type) and issubclass(entry, Logger)
    return None if ok else f"{entry!r} is not a subclass of viz.loggers.base.Logger"


REGISTRY: Registry[type[Logger]] = Registry(
    "logger", "viz.loggers", "viz.loggers", _is_logger, skip=("base", "checker")
)


def register(cls: type[Logger]) -> type[Logger]:
    """Class decorator: add a logger to the registry under its ``name``."""
    return REGISTRY.add(cls.__dict__.get("name", ""), cls)


def failure(error: Exception) -> str:
    """A tracker's error as one short line: its type and the first line of its message."""
    text = str(error).strip()
    return f"{type(error).__name__}: {one_line(text.splitlines()[0] if text else '')[:160]}"


def check_spec(spec: str) -> None:
    """``--logger NAME[=VALUE]``: a known name, and a value only where the logger takes one."""
    name, equals, value = spec.partition("=")
    names = REGISTRY.names()
    if name not in names:
        hint = did_you_mean(name, names)
        raise InputError(f"--logger {name!r}: unknown{hint} (known: {', '.join(names)})")
    cls = REGISTRY.entries[name]
    takers = [n for n in names if REGISTRY.entries[n].value]
    if equals and (not cls.value or not value):
        taking = " and ".join(f"{n}={REGISTRY.entries[n].value}" for n in takers)
        raise InputError(f"--logger {spec[:80]!r}: only {taking} take a value")
    if equals and cls.values and value not in cls.values:
        raise InputError(f"--logger {spec[:80]!r}: {name}'s value is {' or '.join(cls.values)}")


def prepare_tracking(specs: tuple[str, ...], group: Path) -> None:
    """Create what the jobs' loggers share (the MLflow store and experiment of ``group``)
    before they run: two jobs creating it at once would race."""
    for spec in specs:
        name, _, value = spec.partition("=")
        REGISTRY.get(name).prepare(group.resolve(), value or None)


def log_outputs(specs: tuple[str, ...], run_folder: Path, group: Path, files: list[Path]) -> None:
    """Hand a finished run's report, figures and recording to every logger that keeps files."""
    for spec in specs:
        name, _, value = spec.partition("=")
        REGISTRY.get(name).log_outputs(run_folder.resolve(), group.resolve(), value or None, files)


def make_loggers(
    specs: tuple[str, ...],
    folder: Path,
    epochs: int,
    tasks: list[str],
    run_folder: Path | None = None,
    params: dict[str, Any] | None = None,
    group: Path | None = None,
) -> list[Logger]:
    """The loggers ``specs`` name, for the job in ``folder`` of the run in ``run_folder``, one
    of the runs of ``group`` (a sweep's or benchmark's folder; default: the run's own)."""
    loggers = []
    for spec in specs:
        name, _, value = spec.partition("=")
        options = {"run_folder": run_folder, "params": params, "uri": value or None, "group": group}
        loggers.append(REGISTRY.get(name)(folder, epochs, tasks, **options))
    return loggers


def epoch_step(task: int, epoch: int, epochs: int) -> int:
    """The global epoch of ``epoch`` of task ``task``, counted across the curriculum."""
    return task * epochs + epoch


def task_step(task: int, epochs: int) -> int:
    """The global epoch that ended task ``task``: where its results are logged."""
    return max(0, epoch_step(task + 1, -1, epochs))


def diagnostic_scalars(diagnostics: dict[str, Any]) -> Iterator[tuple[str, float]]:
    """The numbers of a task's diagnostics; per-task lists averaged over the tasks seen."""
    for key, value in diagnostics.items():
        if isinstance(value, list):
            value = float(np.mean(value)) if value else None
        if isinstance(value, int | float):
            yield key, float(value)


def scalars(event: str, data: dict[str, Any], epochs: int, tasks: list[str]) -> Iterator:
    """(step, name, value) of every number of a trainer event."""
    if event == "epoch_end":
        step = epoch_step(data["task"], data["epoch"], epochs)
        for key, value in data.items():
            if key not in ("task", "epoch"):
                yield step, key, float(value)
    elif event == "task_end":
        step = task_step(data["task"], epochs)
        for metric in ROW_METRICS:
            for name, value in zip(tasks, data["row"].get(metric, []), strict=False):
                yield step, f"matrix_{metric}/{name}", float(value)
        for key, value in diagnostic_scalars(data.get("diagnostics") or {}):
            yield step, f"diagnostics/{key}", value
        for key, value in (data.get("summary") or {}).items():  # seen/ade, forgetting/ade...
            yield step, key, float(value)


def flat_params(tree: dict[str, Any], prefix: str = "") -> dict[str, str | int | float | bool]:
    """A nested configuration as ``scope.key`` parameters; lists and None as text."""
    out: dict[str, str | int | float | bool] = {}
    for key, value in tree.items():
        name = f"{prefix}{key}"
        if isinstance(value, dict):
            out.update(flat_params(value, f"{name}."))
        else:
            out[name] = value if isinstance(value, str | int | float | bool) else str(value)
    return out
