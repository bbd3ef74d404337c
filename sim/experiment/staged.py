"""Tuning by the staged design (``design.py``): every method's learning rate on one log grid,
then its own knobs one at a time, every setting on the same data draws, each stage's choice
fitted through its runs. The runs are ordinary one-seed experiments on validation data (as
Optuna's trials are: ``trials.py``), each in a folder named by its stage, settings and draw, so
a killed tuning resumes to the same choices: the design reads only finished runs, and the runs
a round asks again resume from their folders. A folder is named by the settings and the draw
alone, so settings two stages share (a stage's centre, the chosen, the defaults) run once.

Returns, per method, what ``run_tuning`` returns (``settings``, ``objective``,
``default_objective``, ``trials``: every run) plus ``stages`` (each knob's points, their means,
the choice and how it was found), ``kept`` (the stages' choice, or the defaults where they scored
better) and ``at_bound`` (the knobs chosen within 5 % of a bound)."""

from __future__ import annotations

import hashlib
import json
import math
import zlib
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from c2inet.errors import InputError
from c2inet.options import Choice
from sim.experiment.config import Execution, ExperimentConfig
from sim.experiment.design import Design, choose, near_bound
from sim.experiment.folders import MARKER, mark_run
from sim.experiment.sweep import layered, plan, run_together
from sim.experiment.trials import (
    TRIAL_TRAIN,
    as_settings,
    check_metric,
    objective_so_far,
    validation_inputs,
)
from sim.experiment.tuning import default_params, search_space, write_chosen


def draw_seed(seed: int, draw: int) -> int:
    """The root seed of data draw ``draw`` of a tuning of root seed ``seed``: the same for every
    setting and method (common random numbers), another for another tuning seed."""
    derived = np.random.SeedSequence([seed, draw, zlib.crc32(b"staged-draw")])
    return int(derived.generate_state(1)[0] % 2**31)


@dataclass
class MethodSearch:
    """One method's walk through its stages: the knobs in order (the learning rate first), the
    values fixed so far, the current stage's points, and every run's record."""

    method: str
    space: dict[str, Any]
    fixed: dict[str, Any]
    defaults: dict[str, Any]
    order: list[str]
    stage: int = 0
    points: list[Any] = field(default_factory=list)
    extended: int = 0
    stages: list[dict[str, Any]] = field(default_factory=list)
    runs: dict[str, dict[str, Any]] = field(default_factory=dict)  # folder name -> record

    @property
    def key(self) -> str | None:
        return self.order[self.stage] if self.stage < len(self.order) else None

    def params(self, value: Any) -> dict[str, Any]:
        return {**self.fixed, self.key: value}


@dataclass
class Runner:
    """What every run of one tuning shares: the tuning experiment, the design, the folder, the
    backend, and each draw's data (prepared once)."""

    base: ExperimentConfig
    design: Design
    out: Path
    execution: Execution
    metric: str = "ade_k1"  # what the board ranks (c2inet.report.RANKABLE)
    curricula: dict[int, Any] = field(default_factory=dict)

    def score(self, wanted: list[tuple[MethodSearch, str, dict[str, Any]]]) -> list[float]:
        """Every (search, stage name, params) on every draw, run together (those already run
        are read from the search); the mean objective of each over the draws (infinite where
        one diverged)."""
        planned, owners, asked = [], [], set()
        for search, stage, params in wanted:
            for draw in range(self.design.draws):
                name = run_name(params, draw)
                if name not in search.runs and (search.method, name) not in asked:
                    asked.add((search.method, name))  # one run, however many stages ask it
                    planned.append(self.plan(search.method, params, draw, name))
                    owners.append((search, stage, params, draw, name))
        done = run_together(planned, self.execution, resume=True, argv=[], figures=False)
        for (search, stage, params, draw, name), (_, (job,)) in zip(owners, done, strict=True):
            final = float(objective_so_far(job.result, self.metric)[-1])
            search.runs[name] = {
                "stage": stage,
                "params": params,
                "draw": draw,
                "seed": draw_seed(self.base.seed, draw),
                "objective": round(final, 6) if math.isfinite(final) else None,
                "cpu_seconds": job.cpu_seconds,
            }
        return [float(np.mean(self.draws(search, params))) for search, _, params in wanted]

    def draws(self, search: MethodSearch, params: dict[str, Any]) -> list[float]:
        return on_draws(search, params, self.design.draws)

    def plan(self, method: str, params: dict[str, Any], draw: int, name: str):
        """One run: ``method`` with ``params`` on draw ``draw``'s data, validation splits only."""
        settings = as_settings(method, params)
        settings["train"] = {**settings.get("train", {}), **TRIAL_TRAIN}
        base = self.base
        config = replace(
            base.only(method, layered(base, settings)), seed=draw_seed(base.seed, draw)
        )
        folder = self.out / "trials" / method / name
        resumed = (folder / "config.json").is_file()
        label, config, folder, curriculum = plan(
            f"{method} {name}", config, folder, self.execution, resumed, self.curricula.get(draw)
        )
        if draw not in self.curricula:  # one draw's data, held out once, for every run on it
            curriculum.inputs = validation_inputs(curriculum)
            self.curricula[draw] = curriculum
        return label, config, folder, curriculum


def run_staged(
    base: ExperimentConfig,
    design: Design,
    out: Path,
    execution: Execution | None = None,
    metric: str = "ade_k1",
) -> dict[str, dict[str, Any]]:
    """Tune every method of ``base`` (its scenario: the tuning curriculum; its seed: the
    tuning's) by ``design`` under ``out``, scored by ``metric``, resuming what a killed tuning
    left; returns each method's choice, also written to ``out/tuning.json``."""
    out.mkdir(parents=True, exist_ok=True)
    if not (out / MARKER).is_file():  # ours, for --overwrite
        mark_run(out)
    base = replace(base, seeds=1, record=False)
    runner = Runner(base, design, out, execution or Execution(), check_metric(metric))
    searches = []
    for method in base.methods:
        space = search_space(method)
        if space:
            defaults = default_params(method, space, base)
            order = ["train.lr", *sorted(k for k in space if k != "train.lr")]
            search = MethodSearch(method, space, dict(defaults), defaults, order)
            search.points = design.first_points(search.key, space[search.key], defaults[search.key])
            searches.append(search)
    while active := [s for s in searches if s.key is not None]:
        means = iter(runner.score([(s, s.key, s.params(v)) for s in active for v in s.points]))
        for search in active:
            advance(search, design, {v: next(means) for v in search.points})
    # the chosen settings and the defaults once more, on the same draws: their objectives
    runner.score([(s, "chosen", s.fixed) for s in searches])
    runner.score([(s, "defaults", s.defaults) for s in searches])
    chosen = {
        s.method: record(s, runner.draws(s, s.fixed), runner.draws(s, s.defaults), design)
        for s in searches
    }
    return write_chosen(out, base.methods, chosen)


def advance(search: MethodSearch, design: Design, means: dict[Any, float]) -> None:
    """Close the current stage, or widen it by a point past the edge its best lies at."""
    space = search.space[search.key]
    finite = {v: m for v, m in means.items() if math.isfinite(m)}
    if finite and search.extended < design.extend and not isinstance(space, Choice):
        best = min(finite, key=lambda v: (finite[v], str(v)))
        ordered = sorted(search.points)
        if best in (ordered[0], ordered[-1]) and len(ordered) > 1:
            new = design.beyond(space, ordered, low_side=best == ordered[0])
            if new is not None:
                search.points = [*search.points, new]
                search.extended += 1
                return
    value, how = choose(space, means)
    side = near_bound(space, value)
    search.stages.append(
        {
            "knob": search.key,
            "points": [{"value": v, "mean": _finite(m)} for v, m in means.items()],
            "chosen": value,
            "how": how,
            **({"at_bound": side} if side else {}),
        }
    )
    search.fixed[search.key] = value
    search.stage, search.extended = search.stage + 1, 0
    if search.key is not None:
        key = search.key
        search.points = design.first_points(key, search.space[key], search.defaults[key])


def record(
    search: MethodSearch,
    chosen: list[float],
    defaults: list[float],
    design: Design | None = None,
) -> dict[str, Any]:
    """A method's entry of ``tuning.json`` and of the artefact, from the stages' choice's and
    the defaults' scores on each draw (infinite where a run diverged). The defaults are a
    candidate, as they are Optuna's first trial: where they beat the choice on the same draws
    (by ``design.keep_defaults``) they are kept (``kept``), since a walk one knob at a time can
    end worse than it began (C2INet-online on density: 0.450 chosen against 0.439)."""
    rule = design or Design()
    kept = "defaults" if rule.keeps_defaults(defaults, chosen) else "stages"
    params = search.defaults if kept == "defaults" else search.fixed
    return {
        "settings": as_settings(search.method, params),
        "objective": _finite(float(np.mean(chosen))),
        "default_objective": _finite(float(np.mean(defaults))),
        "kept": kept,
        "stages": search.stages,
        "at_bound": {
            k: side for k, v in params.items() if (side := near_bound(search.space[k], v))
        },
        "trials": list(search.runs.values()),
    }


def on_draws(search: MethodSearch, params: dict[str, Any], draws: int) -> list[float]:
    """A setting's score on each draw, already run (infinite where it diverged)."""
    scores = [search.runs[run_name(params, d)]["objective"] for d in range(draws)]
    return [math.inf if s is None else s for s in scores]


def reselect(artefact: dict[str, Any], design: Design) -> dict[str, dict[str, Any]]:
    """Every method's entry of a staged ``artefact`` chosen anew from the runs it recorded,
    keeping the defaults by ``design.keep_defaults``: another rule costs no run. The stages'
    choices are the artefact's, the defaults the package's (as every shipped tuning's were; a
    tuning made under ``--set train.lr=...`` had others, and its runs would not be found)."""
    methods = artefact["methods"]
    base = ExperimentConfig(scenario=artefact["scenario"], methods=tuple(methods))
    draws = artefact["design"]["draws"]
    out = {}
    for method, entry in methods.items():
        if "kept" not in entry:  # nothing to tune
            out[method] = entry
            continue
        space = search_space(method)
        defaults = default_params(method, space, base)
        fixed = {stage["knob"]: stage["chosen"] for stage in entry["stages"]}
        runs = {run_name(r["params"], r["draw"]): r for r in entry["trials"]}
        search = MethodSearch(
            method, space, {k: fixed[k] for k in defaults}, defaults, list(defaults),
            stages=entry["stages"], runs=runs,
        )  # fmt: skip
        try:
            chosen = on_draws(search, search.fixed, draws)
            default = on_draws(search, defaults, draws)
        except KeyError:
            raise InputError(f"{method}: no recorded run of {defaults} (tuned under other "
                             "defaults?): cannot reselect") from None  # fmt: skip
        out[method] = record(search, chosen, default, design)
    return out


def run_name(params: dict[str, Any], draw: int) -> str:
    """A run's folder name (under ``trials/METHOD/``): a digest of its settings, and its draw."""
    text = json.dumps(params, sort_keys=True, default=str)
    digest = hashlib.sha256(text.encode()).hexdigest()[:10]
    return f"{digest}-draw{draw}"


def _finite(value: float) -> float | None:
    return round(value, 6) if math.isfinite(value) else None
