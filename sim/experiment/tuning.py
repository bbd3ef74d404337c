"""Tuning with an equal budget: every method gets the same number of Optuna trials over the
learning rate and its own key knobs (``Method.search_space``), scored on validation data only.

A trial is an ordinary one-seed experiment on the *tuning curriculum* (a separate scenario, or by
default the first task of the evaluated one) whose test splits are replaced by validation splits
(or, where a domain has none, by the last fifth of its training scenes, kept out of training): no
trial ever reads a test split or a task the tuning curriculum does not hold. The objective is the
final average point-prediction ADE over the tuning tasks, forgetting included. The first trial of
every method is its defaults, so tuning never selects worse than the defaults on its objective.

The trials of one round run together on the run's backend: one per method, except that a
method's first round holds all its start-up trials (its defaults and the random draws before TPE
starts, which no result can change), so a method of 6 trials takes 4 rounds, not 6. After the
start-up draws TPE asks, or with ``sampler="gp"`` Optuna's Gaussian process. The studies live
in SQLite beside the run (``--storage URL`` for a shared database, ``journal:FILE`` for Optuna's
journal); the sampler is re-seeded
from the seed, the method and the trial's index before each ask, so a killed tuning resumes to
the same choices: unfinished trials are failed and asked again, and their jobs resume from their
own folders.

With ``prune`` (off by default), bad trials stop early by Optuna's median rule: after each
tuning task past the first ``warmup_tasks`` but the last, a trial stops when its objective so far
(the average point-prediction ADE over the tasks it has learnt) is worse than the median of the
finished trials' at that task. The bounds are fixed when the trial is asked, from the trials
finished before it, so a resumed tuning prunes the same trials; the defaults run alone first,
so the draws after them are measured against them. A pruned trial counts in the budget and is
never chosen; TPE reads it as worse than the finished. Measured, pruning saved little and could
discard the best trial (``docs/runs.md``), hence off.

With ``race`` (the best few trials, off by default), the choice is not the best single score:
after the trials, each method's ``race`` best complete trials are scored again on
``race_seeds`` more tuning seeds (each drawing its own data and initialisation), and the one with
the best mean over all its seeds is chosen (``race.py``; its runs live beside the trials and
resume like them; the studies are unchanged by it). Measured on radius, neither the race, nor a
tuning curriculum as long as the evaluated one, nor the Gaussian process made two tunings agree
within the seed spread for every method (``docs/benchmark.md``); hence all three are off.
"""

from __future__ import annotations

import json
import math
import zlib
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
import optuna
from optuna.distributions import CategoricalDistribution, FloatDistribution, IntDistribution
from optuna.trial import TrialState

from c2inet.errors import InputError
from c2inet.files import write_text_atomic
from c2inet.methods.base import get_method
from c2inet.options import Choice, Tunable
from c2inet.trainer import TRAIN_SPACE, Result
from sim.experiment.config import Execution, ExperimentConfig
from sim.experiment.folders import MARKER, mark_run
from sim.experiment.race import race_best
from sim.experiment.storage import check_storage, storage_of
from sim.experiment.sweep import Planned, layered, plan, run_together
from sim.experiment.trials import (
    TRIAL_TRAIN,
    as_settings,
    check_metric,
    objective_so_far,
    trial_seconds,
    validation_inputs,
)


@dataclass(frozen=True)
class TuneConfig:
    """What to tune: ``base`` is the tuning experiment (its scenario is the tuning curriculum;
    its methods are tuned, its ``--set`` settings are every trial's starting point);
    ``trials`` per method, the same for all."""

    base: ExperimentConfig
    trials: int = 6
    storage: str | None = None  # an Optuna storage URL; default: SQLite beside the run
    prune: bool = False  # stop trials worse than the median of the finished ones
    warmup_tasks: int = 1  # tasks after which no trial is stopped (Optuna's n_warmup_steps)
    # what the studies' names start with: a benchmark's key, so that a shared storage never
    # mixes the trials of two benchmarks (or two protocols) under one method's name
    study_prefix: str = ""
    race: int = 0  # the best trials of a method scored again on more seeds (0: none)
    race_seeds: int = 2  # the seeds each raced trial gets beyond its own
    sampler: str = "tpe"  # after the start-up draws: Optuna's TPE, or its Gaussian process
    metric: str = "ade_k1"  # what a trial is scored by (c2inet.report.RANKABLE)

    def __post_init__(self):
        check_metric(self.metric)
        if self.prune and self.metric != "ade_k1":
            raise InputError(
                "--prune stops trials on the point prediction's ADE; not with best of K"
            )
        if self.trials < 1:
            raise InputError(f"trials must be at least 1, got {self.trials}")
        if self.warmup_tasks < 0:
            raise InputError(f"warmup tasks must be at least 0, got {self.warmup_tasks}")
        if self.race < 0:
            raise InputError(f"race must be at least 0 trials, got {self.race}")
        if self.race_seeds < 1:
            raise InputError(f"race seeds must be at least 1, got {self.race_seeds}")
        if self.sampler not in SAMPLERS:
            raise InputError(f"sampler {self.sampler!r}: expected one of {', '.join(SAMPLERS)}")


def search_space(method: str) -> dict[str, Tunable | Choice]:
    """The options a tuner searches for ``method``: none for a method that does not train."""
    cls = get_method(method)
    return {**TRAIN_SPACE, **cls.search_space} if cls.trains else {}


def _check_params(study: str, method: str, params: dict[str, Any]) -> None:
    """Refuse a stored trial whose settings this benchmark's search could not have asked: a
    key outside the method's search space (the ``data`` scope, say) or a value outside its
    range. Such a trial is not ours, and would become the choice unseen."""
    space = search_space(method)
    for key, value in params.items():
        if key not in space or not space[key].holds(value):
            raise InputError(
                f"tuning: the stored study {study!r} holds a trial with {key}={value!r}, which "
                f"{method}'s search space could not ask; not this benchmark's (another --storage "
                "or --overwrite)"
            )


def startup_trials(trials: int) -> int:
    """The trials of a method drawn at random (its defaults first) before TPE starts."""
    return max(1, trials // 2)


SAMPLERS = ("tpe", "gp")  # Optuna's tree-structured Parzen estimator, its Gaussian process


def _sampler(seed: int, method: str, index: int, trials: int, kind: str = "tpe", prefix: str = ""):
    """The sampler that asks trial ``index`` of ``method``, seeded from the tuning's seed, the
    method, the index (a resumed tuning asks the same settings) and the preset's name, the
    first part of the benchmark's key ``prefix`` (``NAME-HASH:``): two presets never draw the
    same design, while one preset's draws never depend on the curriculum it evaluates."""

    parts = [seed, zlib.crc32(method.encode()), index]
    name = prefix.rsplit("-", 1)[0]
    if name and name != "custom":  # the boards tuned before issue 60 drew without it
        parts.append(zlib.crc32(name.encode()))
    derived = np.random.SeedSequence(parts)
    seed, startup = int(derived.generate_state(1)[0]), startup_trials(trials)
    if kind == "gp":  # models the objective's noise (deterministic_objective=False)
        return optuna.samplers.GPSampler(seed=seed, n_startup_trials=startup)
    return optuna.samplers.TPESampler(seed=seed, n_startup_trials=startup)


def _round_size(finished: int, trials: int, prune: bool) -> int:
    """How many trials a method asks in the next round, ``finished`` of ``trials`` done: the
    start-up trials are drawn without reading any result (TPE ignores running trials), so
    asking them together gives the same settings as asking them one by one. When pruning, the
    defaults run alone first: the draws after them are measured against them."""
    if prune and finished == 0:
        return 1
    if finished < startup_trials(trials):
        return startup_trials(trials) - finished
    return 1


def default_params(
    method: str, space: dict[str, Tunable | Choice], base: ExperimentConfig
) -> dict[str, Any]:
    """The values the base configuration gives the searched options: the first trial."""
    sources = {
        "train": base.train_config(),
        "model": base.model_config(),
        "": base.method(method).options,
    }
    out = {}
    for key in space:
        scope, _, name = key.rpartition(".")
        out[key] = getattr(sources[scope], name)
    return out


def _finite(value: float) -> float | None:
    """An objective for JSON: a diverged trial's infinity as null."""
    return value if math.isfinite(value) else None


def _distribution(space: Tunable | Choice):
    """The Optuna distribution of one searched range or choice."""

    if isinstance(space, Choice):
        return CategoricalDistribution(space.values)
    if space.integer:
        return IntDistribution(int(space.low), int(space.high), log=space.log)
    return FloatDistribution(space.low, space.high, log=space.log)


def stop_bounds(curves: list[list[float]], tasks: int, warmup: int) -> tuple[float | None, ...]:
    """A trial's pruning bounds, one per tuning task but the last: the median of the finished
    trials' objectives so far (``curves``, one per trial) after that task (Optuna's
    ``MedianPruner`` rule), None for the first ``warmup`` tasks; empty before the first trial
    finishes."""
    if not curves:
        return ()
    return tuple(
        float(np.median([c[t] for c in curves])) if t >= warmup else None for t in range(tasks - 1)
    )


def run_tuning(
    tune: TuneConfig, out: Path, execution: Execution | None = None
) -> dict[str, dict[str, Any]]:
    """Tune every method of ``tune.base`` under ``out``, continuing whatever an earlier, killed
    tuning left there; returns per method its chosen settings (``settings``, by scope), their
    objective, the defaults' objective and every trial. Also written to ``out/tuning.json``."""

    optuna.logging.set_verbosity(optuna.logging.WARNING)
    execution = execution or Execution()
    out.mkdir(parents=True, exist_ok=True)
    if not (out / MARKER).is_file():  # ours, for --overwrite: its studies and its trial folders
        mark_run(out)
    base = replace(tune.base, seeds=1, record=False)
    tuned = [m for m in base.methods if search_space(m)]
    studies = open_studies(tune, out, tuned)

    def finished(method: str, states=(TrialState.COMPLETE, TrialState.PRUNED)) -> list:
        return studies[method].get_trials(deepcopy=False, states=states)

    def plan_trial(method: str, index: int, params: dict[str, Any]) -> Planned:
        """The experiment of one trial, in its folder, on the validation splits, with the
        bounds that stop it early when pruning."""
        settings = as_settings(method, params)
        settings["train"] = {**settings.get("train", {}), **TRIAL_TRAIN}
        if tune.prune:
            complete = finished(method, (TrialState.COMPLETE,))
            curves = [_curve(t) for t in complete if len(t.intermediate_values) == tasks]
            settings["train"]["stop_above"] = stop_bounds(curves, tasks, tune.warmup_tasks)
        config = base.only(method, layered(base, settings))
        folder = out / "trials" / method / f"trial_{index:03d}"
        resumed = (folder / "config.json").is_file()  # a trial a killed tuning began
        label, config, folder, curriculum = plan(
            f"{method} {index}", config, folder, execution, resumed
        )
        curriculum.inputs = validation_inputs(curriculum)
        return label, config, folder, curriculum

    tasks = len(base.specs)
    while pending := [m for m in tuned if len(finished(m)) < tune.trials]:
        asked, planned = [], []
        for method in pending:
            space, count = search_space(method), len(finished(method))
            study = studies[method]
            if count == 0 and not study.get_trials(deepcopy=False, states=(TrialState.WAITING,)):
                study.enqueue_trial(default_params(method, space, base))  # the defaults come first
            for index in range(count, count + _round_size(count, tune.trials, tune.prune)):
                study.sampler = _sampler(
                    base.seed, method, index, tune.trials, tune.sampler, tune.study_prefix
                )
                trial = study.ask({key: _distribution(s) for key, s in space.items()})
                asked.append((method, trial))
                planned.append(plan_trial(method, index, trial.params))
        costs = [trial_seconds(out, method) for method, _ in asked]  # the longest start first
        done = run_together(planned, execution, resume=True, argv=[], costs=costs, figures=False)
        for (method, trial), (_, (job,)) in zip(asked, done, strict=True):  # in index order
            tell(studies[method], trial, job.result, tasks, tune.metric)
    raced = race_best(tune, out, execution, studies, tuned) if tune.race else {}
    return write_chosen(out, base.methods, {m: choice(m, studies[m], raced.get(m)) for m in tuned})


def write_chosen(out: Path, methods, tuned: dict[str, dict[str, Any]]) -> dict[str, dict]:
    """Every method's choice (nothing, for one with nothing to tune) into ``out/tuning.json``."""
    chosen = {m: {"settings": {}, "trials": []} for m in methods if m not in tuned} | tuned
    write_text_atomic(out / "tuning.json", json.dumps(chosen, indent=1) + "\n")
    return chosen


def open_studies(tune: TuneConfig, out: Path, methods: list[str]) -> dict[str, Any]:
    """Each method's Optuna study in the tuning's store (``out/tuning.db`` unless
    ``tune.storage``), created or loaded; a damaged store or a study that is not ours is one
    line, and the trials a killed tuning left running are failed, to be asked again."""

    url = tune.storage or f"sqlite:///{(out / 'tuning.db').resolve()}"
    if tune.storage is None:  # our own store, damaged since: one line, not the driver's error
        check_storage(url, f"the tuning store {out / 'tuning.db'} (delete it to tune again)")
    storage = storage_of(url)
    studies = {}
    for method in methods:
        study = optuna.create_study(
            study_name=f"{tune.study_prefix}{method}",
            storage=storage,
            direction="minimize",
            load_if_exists=True,
        )
        if study.direction != optuna.study.StudyDirection.MINIMIZE:
            raise InputError(f"tuning: the stored study {study.study_name!r} maximises; not ours")
        for trial in study.get_trials(deepcopy=False, states=(TrialState.RUNNING,)):
            study.tell(trial.number, state=TrialState.FAIL)  # killed: asked again below
        studies[method] = study
    return studies


def tell(study, trial, result: Result, tasks: int, metric: str = "ade_k1") -> None:
    """Report a finished trial's objective after each task it learnt and close it: complete,
    or pruned if it stopped early. A diverged trial is the worst there is, not a failure to ask
    again (same seed, same history: the same settings, for ever)."""

    curve = [round(float(v), 6) for v in objective_so_far(result, metric)]  # as metrics.json
    for task, value in enumerate(curve):
        trial.report(value if math.isfinite(value) else math.inf, task)
    if len(curve) < tasks:
        study.tell(trial, state=TrialState.PRUNED)
    else:
        study.tell(trial, curve[-1] if math.isfinite(curve[-1]) else math.inf)


def choice(method: str, study, raced: dict[int, list[float]] | None = None) -> dict[str, Any]:
    """The best complete trial of ``method``'s study (the earliest of equals) as its chosen
    settings, beside the defaults' objective and every trial, in the order they were asked.
    With ``raced`` (trial number: its objectives over the race's seeds), the raced trial of the
    best mean is chosen, and ``objective`` is that mean."""

    trials = study.get_trials(deepcopy=False, states=(TrialState.COMPLETE, TrialState.PRUNED))
    complete = [t for t in trials if t.state == TrialState.COMPLETE]
    best = min(complete, key=lambda t: (t.value, t.number))
    objective = best.value
    if raced:
        means = {number: float(np.mean(scores)) for number, scores in raced.items()}
        number = min(means, key=lambda n: (means[n], n))
        best, objective = next(t for t in trials if t.number == number), means[number]
    _check_params(study.study_name, method, best.params)
    record = {
        "settings": as_settings(method, best.params),
        "objective": _finite(objective),
        "default_objective": _finite(trials[0].value),  # the first trial is the defaults
        "trials": [_trial_record(t) for t in trials],
    }
    if raced:
        record["race"] = [
            {"trial": n, "objectives": [_finite(v) for v in scores], "mean": _finite(means[n])}
            for n, scores in raced.items()
        ]
    return record


def _curve(trial) -> list[float]:
    """A finished trial's objective so far after each task it learnt, as it reported them."""
    return [trial.intermediate_values[t] for t in sorted(trial.intermediate_values)]


def _trial_record(trial) -> dict[str, Any]:
    """A trial for ``tuning.json``: its settings, its objective (null when pruned or diverged),
    whether it was pruned, and its objective so far after each task it learnt."""

    curve, pruned = _curve(trial), trial.state == TrialState.PRUNED
    return {
        "params": trial.params,
        "objective": None if pruned else _finite(trial.value),
        "pruned": pruned,
        "tasks": len(curve),
        "objective_so_far": [_finite(v) for v in curve],
    }
