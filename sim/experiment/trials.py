"""What a tuning trial is: a one-seed experiment on validation data (the test splits replaced,
or the end of the training scenes held out), lean, scored by its final ADE (the point
prediction's, or the best of K where the board ranks that);
and what its finished runs cost. Shared by the tuning (``tuning.py``) and its race
(``race.py``)."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np

from c2inet.errors import InputError
from c2inet.metrics import average_seen
from c2inet.report import RANKABLE
from c2inet.trainer import Result, Task
from sim.experiment.curriculum import Curriculum, JobInputs

HOLDOUT = 0.2  # share of a domain's training scenes held out where it has no validation split

# what a trial's objective (the final point-prediction ADE) never reads, so trials skip it: the
# diagnostics, the per-epoch validation curves, the latent models' other test-time rules and the
# tasks not yet learnt
TRIAL_TRAIN = {"diagnostics": False, "val_every": 0, "test_rules": False, "eval_unseen": False}


def as_settings(method: str, params: dict[str, Any]) -> dict[str, dict[str, Any]]:
    """Trial parameters (``train.lr``, ``strength``...) as ``--set`` settings by scope."""
    settings: dict[str, dict[str, Any]] = {}
    for key, value in params.items():
        scope, _, name = key.rpartition(".")
        settings.setdefault(scope or method, {})[name] = value
    return settings


def validation_inputs(curriculum: Curriculum) -> JobInputs:
    """The tasks with their test splits replaced by validation data: what a trial is scored
    on. A domain without a validation split gives up the last fifth of its training scenes."""
    tasks = []
    for task in curriculum.inputs.tasks:
        train, val = task.train, task.val
        if val is None:
            kept = max(1, math.floor(len(train) * (1 - HOLDOUT)))
            if kept >= len(train):
                raise InputError(f"tuning: {task.name} has too few scenes to hold some out")
            train, val = train.subset(np.arange(kept)), train.subset(np.arange(kept, len(train)))
        tasks.append(Task(task.name, train, val, val, task.value))
    return JobInputs(tasks, [])


def check_metric(metric: str) -> str:
    """``metric`` if a board can rank by it, else one line naming the choices."""
    if metric not in RANKABLE:
        raise InputError(f"metric {metric!r}: expected one of {', '.join(RANKABLE)}")
    return metric


def objective_so_far(result: Result, metric: str = "ade_k1") -> np.ndarray:
    """After each task a trial learnt, its average ADE (``metric``: the point prediction's or
    the best of K) over the tasks so far (the last one, after the last task, is the objective)."""
    return average_seen(result.matrices[metric][: len(result.summaries)])  # one a task learnt


def trial_paths(out: Path, method: str) -> list[Path]:
    """The ``result.json`` path of every finished trial job of ``method`` under the tuning
    folder ``out``, pruned ones and the race's runs included."""
    return list((out / "trials" / method).glob("*/jobs/*/seed_*/result.json"))


def trial_results(out: Path, method: str) -> list[dict[str, Any]]:
    """The ``result.json`` of every finished trial job of ``method`` (:func:`trial_paths`)."""
    return [json.loads(path.read_text()) for path in trial_paths(out, method)]


def trial_seconds(out: Path, method: str) -> float:
    """The mean CPU seconds of ``method``'s finished trials under the tuning folder ``out`` that
    learnt every task (a pruned one's is part of a trial; 0 before the first): what orders the
    trials and evaluation jobs, longest first."""
    results = trial_results(out, method)
    spent = [r.get("cpu_seconds") or 0.0 for r in results if len(r["summaries"]) == len(r["tasks"])]
    return float(np.mean(spent)) if spent else 0.0
