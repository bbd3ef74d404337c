"""An experiment's configuration: what it computes (:class:`ExperimentConfig`), how it runs
(:class:`Execution`), its jobs, and the ``--set SCOPE.KEY=VALUE`` overrides.

Equal configurations give equal ``metrics.json``; every field is checked on construction, bad
input raising ``InputError``.
"""

from __future__ import annotations

import os
from dataclasses import asdict, dataclass, field, replace
from functools import cached_property
from pathlib import Path
from typing import Any

from c2inet.backbones.base import REGISTRY as BACKBONE_REGISTRY
from c2inet.device import resolve_device
from c2inet.errors import InputError
from c2inet.files import check_path_length
from c2inet.methods.base import get_method
from c2inet.model_config import ModelConfig
from c2inet.options import build
from c2inet.trainer import TrainConfig
from sim.experiment.backends import BACKENDS, check_ray_address
from sim.experiment.defaults import DEFAULT_METHODS
from sim.scenario import DomainSpec, parse_scenario
from viz.live import viewer_url
from viz.loggers import check_spec

SHARED_SCOPES = ("data", "model", "train")  # settings scopes besides the methods' own
# options that have a flag of their own: a --set of them would be silently overridden
FLAG_OPTIONS = (
    *(("train", "epochs"), ("train", "k"), ("train", "seed"), ("train", "device")),
    ("model", "backbone"),
)


@dataclass(frozen=True)
class ExperimentConfig:
    """What an experiment computes: equal configurations give equal ``metrics.json``.

    ``settings`` are option overrides by scope (``data``, ``model``, ``train`` or a method's
    name), as ``--set SCOPE.KEY=VALUE`` gives them. ``epochs`` and ``k`` default to 20 (2 and 5 when
    ``quick``). Everything is checked on construction: bad input raises ``InputError``.
    """

    scenario: str
    methods: tuple[str, ...] = DEFAULT_METHODS
    seeds: int = 1
    seed: int = 0
    epochs: int | None = None
    k: int | None = None
    backbone: str = "stgat"
    quick: bool = False
    settings: dict[str, dict[str, Any]] = field(default_factory=dict)
    scenarios_dir: tuple[Path, ...] = ()
    record: bool = True
    device: str = "cpu"  # where the models train: auto, cpu, cuda, cuda:N or mps

    def __post_init__(self):
        fill = object.__setattr__  # the resolved defaults belong to the frozen configuration
        fill(self, "methods", tuple(self.methods))
        fill(self, "scenarios_dir", tuple(Path(p) for p in self.scenarios_dir))
        if not self.specs:  # parsed here, once: a bad scenario or data override fails now
            raise InputError(f"scenario {self.scenario!r}: no domain")
        family = self.family_train
        self._family_table("model")  # a family's bad [model] key names its file, now
        epochs, k = (2, 5) if self.quick else (family.get("epochs", 20), family.get("k", 20))
        fill(self, "epochs", self.epochs if self.epochs is not None else epochs)
        fill(self, "k", self.k if self.k is not None else k)
        self.unit  # noqa: B018  (refuses a curriculum that mixes metres and pixels, now)
        if not self.methods:
            raise InputError("methods: no method named")
        if len(set(self.methods)) != len(self.methods):
            raise InputError(f"methods: a method is named twice in {','.join(self.methods)}")
        for name in self.methods:
            get_method(name)  # an unknown one: UnknownName, an InputError naming the known ones
        self._check_network()
        for scope in self.settings:
            if scope not in (*SHARED_SCOPES, *self.methods):
                raise InputError(
                    f"--set: scope {scope!r} is not data, model, train or a chosen method"
                )

        for scope, key in FLAG_OPTIONS:
            if key in self.settings.get(scope, {}):
                raise InputError(f"--set {scope}.{key}: use --{key} (its flag) instead")
        if self.seed < 0:
            raise InputError(f"seed must be at least 0, got {self.seed}")
        for name, value, low in (
            ("seeds", self.seeds, 1),
            ("epochs", self.epochs, 0),
            ("k", self.k, 1),
        ):
            if value < low:
                raise InputError(f"{name} must be at least {low}, got {value}")
        try:
            self.model_config()
            self.train_config()
            for name in self.methods:
                self.method(name)
        except ValueError as error:
            raise InputError(f"--set {error}") from None

    def _check_network(self) -> None:
        """The device, the backbone and its kernels, before any work: a device this machine
        lacks, an unknown backbone (one line naming the known ones), compiled kernels on a GPU."""
        resolve_device(self.device)  # its own one line, before the kernels it decides
        try:
            self.kernels_used()
        except ValueError as error:
            raise InputError(f"--set {error}") from None

    def kernels_used(self) -> str:
        """Which of the backbone's kernels the jobs run (``model.kernels`` resolved for the
        run's device, ``c2inet.kernels``): compiled, tensor or cell; ``its own`` for a backbone
        that says nothing of them."""
        backbone = BACKBONE_REGISTRY.get(self.backbone)
        if not hasattr(backbone, "kernels_for"):
            return "its own"
        return backbone.kernels_for(self.model_config().kernels, resolve_device(self.device))

    @cached_property
    def specs(self) -> list[DomainSpec]:
        """The curriculum's domains, with the ``data`` settings applied to their knobs (parsed
        once per configuration)."""
        return parse_scenario(self.scenario, list(self.scenarios_dir), self.settings.get("data"))

    @cached_property
    def family_train(self) -> dict[str, Any]:
        """The learner's defaults the curriculum's families set (their ``[train]`` tables: the
        reproduction's schedule and sizes, say), under ``--set train.*`` and the flags; the
        families of one curriculum must agree on them."""
        return self._family_table("train")

    @cached_property
    def family_model(self) -> dict[str, Any]:
        """The network's defaults the families set (their ``[model]`` tables), under
        ``--set model.*``; the families of one curriculum must agree on them."""
        return self._family_table("model")

    def _family_table(self, table: str) -> dict[str, Any]:
        options = {"train": TrainConfig, "model": ModelConfig}[table]
        for spec in self.specs:  # a bad key names the family's file, not --set
            build(options, getattr(spec.family, table), f"{spec.family.path} [{table}]")
        tables = {spec.family.name: getattr(spec.family, table) for spec in self.specs}
        (first_name, first), *_ = tables.items()
        for name, values in tables.items():
            if values != first:
                raise InputError(
                    f"scenario {self.scenario!r}: families {first_name!r} and {name!r} set "
                    f"different [{table}] defaults; run them apart, or give every option by --set"
                )
        return dict(first)

    @cached_property
    def reductions(self) -> tuple[str, ...]:
        """What this configuration trains less than its families' and the learner's defaults
        (scenes a split, the training windows' share, epochs), in words; empty: the full size
        (or ``quick``, marked apart)."""
        if self.quick:
            return ()
        plain = parse_scenario(self.scenario, list(self.scenarios_dir))[0].family
        family, out = self.specs[0].family, []
        for split in ("train", "val", "test"):
            given, default = getattr(family.splits, split), getattr(plain.splits, split)
            if family.generator != "files" and given < default:
                out.append(f"{split} {given} of {default} scenes a task")
        if family.share < plain.share:
            out.append(f"the first {family.share:g} of the training windows")
        default_epochs = self.family_train.get("epochs", 20)
        if self.epochs < default_epochs:
            out.append(f"{self.epochs} of {default_epochs} epochs")
        return tuple(out)

    @property
    def size(self) -> str:
        """``quick``, ``full`` or ``reduced (...)``: what every output calls the run's sizes."""
        if self.quick:
            return "quick"
        return f"reduced ({'; '.join(self.reductions)})" if self.reductions else "full"

    @property
    def unit(self) -> str:
        """What the curriculum's positions, so its errors, are in: ``m`` or ``px``; a curriculum
        that mixes the two has no unit its errors could be averaged in."""
        units = {spec.family.unit for spec in self.specs}
        if len(units) > 1:
            raise InputError(
                f"scenario {self.scenario!r}: mixes families in {' and '.join(sorted(units))}; "
                "averaged errors need one unit"
            )
        return units.pop()

    def model_config(self) -> ModelConfig:
        given = {**self.family_model, "backbone": self.backbone, **self.settings.get("model", {})}
        return build(ModelConfig, given, "model")

    def train_config(self, seed_index: int = 0) -> TrainConfig:
        """The trainer's options of the job with seed ``seed_index`` (its own seed)."""
        family = {k: v for k, v in self.family_train.items() if k not in ("epochs", "k")}
        train = {**family, **self.settings.get("train", {}), "epochs": self.epochs, "k": self.k}
        train["device"] = self.device
        return build(TrainConfig, {**train, "seed": self.seed + seed_index}, "train")

    def method(self, name: str):
        return get_method(name)(self.model_config(), self.settings.get(name))

    def only(self, method: str, settings: dict[str, dict[str, Any]] | None = None):
        """This experiment for ``method`` alone, with ``settings`` (default: its own), less
        the scopes of the other methods."""
        settings = self.settings if settings is None else settings
        kept = {s: v for s, v in settings.items() if s in (*SHARED_SCOPES, method)}
        return replace(self, methods=(method,), settings=kept)

    def jobs(self) -> list[Job]:
        return [Job(m, s) for m in self.methods for s in range(self.seeds)]

    def to_json(self) -> dict[str, Any]:
        return {**asdict(self), "scenarios_dir": [str(p) for p in self.scenarios_dir]}


@dataclass(frozen=True)
class Execution:
    """How an experiment runs; none of it changes a number of ``metrics.json``.

    ``jobs``: local processes (``local``) or the CPUs of the local cluster Ray starts (``ray``,
    unless ``ray_address`` joins an existing one). ``workers``: processes that generate episodes.
    ``rerun``: also stream to a live viewer (``spawn`` or ``connect[=URL]``).
    """

    backend: str = "local"
    jobs: int = 1
    ray_address: str | None = None
    threads: int = 1
    workers: int = os.cpu_count() or 1
    cache: Path = Path(".cache/domains")
    rerun: str | None = None
    loggers: tuple[str, ...] = ()  # csv, tensorboard, mlflow[=URI], wandb[=online] (viz.loggers)
    memory_budget: float | None = None  # GB one domain's generation may take (None: no limit)
    # the folder whose runs the trackers group (one MLflow experiment, one W&B group): a sweep's
    # or a benchmark's, set by it; None: each run its own
    tracking: Path | None = None

    def __post_init__(self):
        object.__setattr__(self, "loggers", tuple(self.loggers))
        object.__setattr__(self, "cache", Path(self.cache))
        for spec in self.loggers:
            check_spec(spec)
        if self.backend not in BACKENDS:
            raise InputError(f"--backend {self.backend!r}: expected one of {', '.join(BACKENDS)}")
        if self.rerun is not None and self.rerun != "spawn":
            if self.rerun != "connect" and not self.rerun.startswith("connect="):
                raise InputError(
                    f"--rerun {self.rerun[:80]!r}: expected spawn, connect or connect=URL"
                )
            viewer_url(self.rerun)
        if check_path_length(self.cache, "--cache").exists() and not self.cache.is_dir():
            raise InputError(f"--cache {self.cache}: not a folder")
        if self.ray_address is not None and self.backend != "ray":
            raise InputError("--ray-address: only with --backend ray")
        if self.ray_address is not None:
            check_ray_address(self.ray_address)  # before the domains and the folder

    def job_options(self, resume: bool) -> dict[str, Any]:
        """The keyword options of :func:`run_job` that come from how the run executes."""
        live, loggers = self.live_target(), self.loggers
        return {
            "threads": self.threads,
            "resume": resume,
            "live": live,
            "loggers": loggers,
            "tracking": self.tracking,
        }

    def live_target(self) -> str | None:
        """Where jobs stream to: the spawned viewer's default address, or the given one."""
        return None if self.rerun is None else "connect" if self.rerun == "spawn" else self.rerun


@dataclass(frozen=True)
class Job:
    """One (method, seed) of an experiment; the curriculum is the experiment's."""

    method: str
    seed_index: int

    def folder(self, out: Path) -> Path:
        return out / "jobs" / self.method / f"seed_{self.seed_index}"


def parse_settings(items: list[str]) -> dict[str, dict[str, Any]]:
    """``SCOPE.KEY=VALUE`` strings -> {scope: {key: value}}, values read as bool, int, float or
    text (the option's type is checked when the configuration is built)."""
    settings: dict[str, dict[str, Any]] = {}
    for item in items:
        key, sep, text = item.partition("=")
        scope, dot, name = key.partition(".")
        if not sep or not dot or not name:
            raise InputError(
                f"--set {item!r}: expected SCOPE.KEY=VALUE, e.g. c2inet-online.pruning=false"
            )
        if name in settings.get(scope, {}):
            raise InputError(f"--set {key}: given twice; give each option once")
        settings.setdefault(scope, {})[name] = parse_value(text)
    return settings


def parse_value(text: str) -> bool | int | float | str:
    """An option value from the command line: true/false, an integer, a number, or text."""
    flag = {"true": True, "false": False}.get(text.strip().lower())
    if flag is not None:
        return flag
    for kind in (int, float):
        try:
            return kind(text)
        except ValueError:
            pass
    return text
