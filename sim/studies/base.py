"""The study skeleton and registry: a study declares its options, runs, and says its table and
figure; the command (``python -m sim.study NAME``) does the rest the same way for every study.

A study is an instance of a :class:`Study` subclass registered with :func:`register` in a module
of ``sim.studies``; :func:`discover` imports them all. What the skeleton does for each: the
shared options (``sim.cli``), the experiment's configuration and execution, one output policy
(the folder ``studies/NAME`` unless ``--out``; a folder holding anything else is refused, and
``--overwrite`` removes only a folder of ours), and ``NAME.json``, ``NAME.md`` and ``NAME.png``.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any

from c2inet.lazy import lazy_module
from c2inet.registry import Registry

if TYPE_CHECKING:  # a study's module stays light at import (the engine, the learner and the
    # figures load in ``run``, ``figure``): listing the studies costs no torch
    from sim.experiment import Execution, ExperimentConfig

# loaded on first use: a command that stops at bad input or answers --help does not pay for it
outputs = lazy_module("sim.experiment.outputs")


def _is_study(entry: Any) -> str | None:
    return None if isinstance(entry, Study) else f"{entry!r} is not a sim.studies.base.Study"


REGISTRY: Registry[Study] = Registry("study", "sim.studies", "sim.studies", _is_study)
STUDIES = REGISTRY.entries  # name -> study


class Study:
    """One study. Every study runs its training as jobs on a backend (``--jobs``, ``--backend``)
    and resumes (``--resume``). ``sweeps``: its jobs are the engine's experiments (a sweep, with
    run folders, ``--logger`` and, if it ``records``, ``--no-record``); otherwise they are
    cells (``sim.experiment.cells``) of its own loop. ``scenarios``: ``--scenario`` may be
    repeated. ``one_method``: ``--methods`` names exactly one learner."""

    name: str = ""
    title: str = ""  # one line, the command's description
    examples: tuple[str, ...] = ()  # argument lists after ``python -m sim.study NAME``
    methods: str = "finetune"  # the default of --methods
    sweeps: bool = False
    scenarios: bool = False
    scenario_required: bool = True
    one_method: bool = False
    records: bool = True  # with ``sweeps``: its runs write recordings (else no --no-record)
    report: str = ""  # the files' name: NAME.json, NAME.md, NAME.png (default: the study's name)

    def __init_subclass__(cls, **kwargs):
        """Without a ``title``, the first line of the study module's docstring after its
        command (``python -m sim.study NAME``: what it does)."""
        super().__init_subclass__(**kwargs)
        doc = sys.modules[cls.__module__].__doc__ or ""
        if "title" not in cls.__dict__ and ": " in doc.split("\n", 1)[0]:
            cls.title = doc.split("\n", 1)[0].split(": ", 1)[1].rstrip(".")

    def scenario_of(self, args: argparse.Namespace) -> str:
        """The scenario of the study's configuration (the first, where it takes several)."""
        return args.scenario[0] if self.scenarios else args.scenario

    def add_options(self, p: argparse.ArgumentParser) -> None:
        """The study's own options (the shared ones are added by the command)."""

    @property
    def folder(self) -> str:
        """Its folder without ``--out``, as the help says it."""
        return f"studies/{self.name}"

    def default_out(self, args: argparse.Namespace) -> Path:
        """Its folder without ``--out``."""
        return Path(self.folder)

    def run(
        self,
        args: argparse.Namespace,
        config: ExperimentConfig,
        execution: Execution,
        out: Path,
        argv: list[str],
    ) -> dict[str, Any] | None:
        """Compute the study into ``out``; returns its report (``NAME.json``), or None where it
        only printed (nothing to write)."""
        raise NotImplementedError

    def markdown(self, report: dict[str, Any]) -> str:
        """``NAME.md``: the study's table."""
        raise NotImplementedError

    def figure(self, report: dict[str, Any], path: Path) -> None:
        """``NAME.png``: the study's figure."""
        raise NotImplementedError

    def write(self, report: dict[str, Any], out: Path) -> str:
        """``NAME.json``, ``NAME.md`` and ``NAME.png`` of ``report`` in ``out``; returns NAME."""
        name = self.report or self.name
        outputs.write_report(out, name, report, self.markdown, self.figure)
        return name


def register(study: Study) -> Study:
    """Add ``study`` to the registry under its name; a name given twice is an error."""
    if not study.name or study.name in REGISTRY.entries:
        raise ValueError(f"study name {study.name!r} is empty or registered twice")
    return REGISTRY.add(study.name, study)


def discover() -> dict[str, Study]:
    """Every study: the modules of ``sim.studies`` register theirs on import, and so do other
    packages' entry points of the group ``sim.studies`` (each a :class:`Study` instance)."""
    return dict(sorted(REGISTRY.discover().items()))


def get_study(name: str) -> Study:
    """The study called ``name`` (an :class:`~c2inet.registry.UnknownName` otherwise)."""
    return REGISTRY.get(name)
