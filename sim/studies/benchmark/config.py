"""The fair benchmark's configuration: what is evaluated, how it is tuned, its key (so a shared
storage never mixes two benchmarks), and how many seeds each method gets."""

from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

from c2inet.errors import InputError
from c2inet.files import file_digest
from c2inet.methods.base import get_method
from c2inet.report import RANKABLE, REFERENCE
from sim.experiment.config import ExperimentConfig
from sim.experiment.design import Design
from sim.experiment.sweep import layered
from sim.experiment.trials import TRIAL_TRAIN, check_metric
from sim.experiment.tuning import SAMPLERS, TuneConfig
from sim.scenario import parse_scenario
from sim.studies.benchmark.artefacts import read_json, read_tuning, shown, tunable_only
from sim.studies.benchmark.presets import (
    BATCH,
    RACE,
    RACE_SEEDS,
    REFERENCE_SEEDS,
    REPLAY_BUDGET,
    SAMPLER,
    SEEDS,
    TRIALS,
)

# what the leaderboard never reads, so evaluation jobs skip it (as tuning trials do)
LEAN = TRIAL_TRAIN


def borrowed_tuning(
    given: Path, base: ExperimentConfig, ranked: tuple[str, ...]
) -> tuple[dict[str, dict[str, Any]], dict[str, Any]]:
    """Another benchmark's chosen settings (``--tuned-from``: a board's folder, its
    ``tuning/`` folder or its ``tuning.json``), each ranked method's checked as ``--set`` is, and
    where they came from (the file, its SHA-256, the curriculum they were tuned on where the
    board's ``leaderboard.json`` says it). The same settings on another curriculum separate what
    the data changes from what a tuning's draw changes (the sim-to-real ranking transfer)."""
    option = "--tuned-from"
    path, artefact, chosen = read_tuning(given, option)
    for method in ranked:
        entry = chosen.get(method)
        settings = entry.get("settings") if isinstance(entry, dict) else None
        if not isinstance(settings, dict) or not all(
            isinstance(v, dict) for v in settings.values()
        ):
            raise InputError(f"{option} {path}: no chosen settings of {method!r}")
        tunable_only(f"{option} {path}: {method}", method, settings)
        try:
            base.only(method, layered(base, settings))  # checked as --set is
        except InputError as error:
            raise InputError(f"{option} {path}: {method}: {error}") from None
    source = {"file": shown(path), "sha256": file_digest(path)}
    boards = [p / "leaderboard.json" for p in (path.parent, path.parent.parent)]
    board = next((b for b in boards if b.is_file()), None)
    if isinstance(artefact.get("tune_scenario"), str):  # an artefact says it itself
        source["tune_scenario"] = artefact["tune_scenario"]
        source["design"] = artefact.get("design")
        source["tuning_seed"] = artefact.get("seed")
    elif board is not None:
        tuned_on = read_json(board, option)
        if isinstance(tuned_on, dict) and isinstance(tuned_on.get("tune_scenario"), str):
            source["tune_scenario"] = tuned_on["tune_scenario"]
        if isinstance(tuned_on, dict) and tuned_on.get("metric") in RANKABLE:
            source["metric"] = tuned_on["metric"]  # what its tuning scored (K = 1 if unsaid)
    # no trial ran here: the board counts none, says whose settings it used, and marks the
    # methods whose tuning kept their defaults (a staged artefact says which)
    return {
        m: {
            "settings": chosen[m]["settings"],
            "trials": [],
            **({"kept": "defaults"} if chosen[m].get("kept") == "defaults" else {}),
        }
        for m in ranked
    }, source


def references(methods: tuple[str, ...]) -> tuple[str, ...]:
    """The methods that are references, not competitors: those that see old tasks' data."""
    return tuple(m for m in methods if get_method(m).sees_old_tasks)


@dataclass(frozen=True, kw_only=True)
class BenchConfig:
    """``base``: the evaluation (scenario, methods, ``seeds`` of every ranked method, sizes,
    ``--set``; the protocol's batch unless ``--set train.batch_scenes``); ``name``: the preset
    (or ``custom``); ``tune_scenario``: the tuning curriculum; ``trials`` per method; ``prune``:
    stop trials worse than the median so far; ``replay_budget``: scenes every replay method
    keeps (None: each its own default); ``reference_seeds``; ``compare``: the decisive pair,
    given seeds until its interval is narrower than ``width`` metres or it has ``max_seeds``;
    ``data``: the preset's data sizes (``Preset.data``), under the user's own ``--set data.*``;
    ``tuning_seed``: the tuning's root seed (its sampler, trials and data) where it is not the
    evaluation's, so two tunings of one benchmark can be compared on the same evaluation;
    ``race``: each method's best trials scored again on ``race_seeds`` more seeds, the best mean
    chosen (``sim.experiment.tuning``); ``sampler``: what asks the trials after the start-up
    draws (``tpe`` or ``gp``); ``tuned_from``: no tuning here, every method's settings taken
    from another benchmark (:func:`borrowed_tuning`): a preset's shipped artefact by default;
    ``design``: tune by the staged design (``sim.experiment.design``: one log grid of learning
    rates, each method's knobs in turn, every setting on the same data draws) instead of Optuna's
    trials (None: Optuna's, with ``trials``, ``sampler``, ``race`` and ``prune``)."""

    base: ExperimentConfig = field(kw_only=False)
    name: str = "custom"
    tune_scenario: str | None = None
    trials: int = TRIALS
    storage: str | None = None
    replay_budget: int | None = REPLAY_BUDGET
    prune: bool = False
    reference_seeds: int = REFERENCE_SEEDS
    compare: tuple[str, ...] = ()
    width: float = 0.01
    max_seeds: int = 30
    data: dict[str, Any] = field(default_factory=dict)
    tuning_seed: int | None = None
    race: int = RACE
    race_seeds: int = RACE_SEEDS
    sampler: str = SAMPLER
    tuned_from: Path | None = None
    design: Design | None = None
    # what the board ranks and its tuning scores (c2inet.report.RANKABLE), and the
    # preset's training recipe (``train``, ``model`` settings) under the user's own --set
    metric: str = "ade_k1"
    recipe: dict[str, dict[str, Any]] = field(default_factory=dict)
    given: dict[str, Any] = field(init=False, compare=False, repr=False)  # the user's --set
    borrowed: tuple | None = field(init=False, compare=False, repr=False)  # (chosen, source)

    def __post_init__(self):
        object.__setattr__(self, "compare", tuple(self.compare))
        object.__setattr__(self, "given", self.base.settings)
        self._check()
        object.__setattr__(self, "base", replace(self.base, settings=self._protocol_settings()))
        borrowed = None
        if self.tuned_from is not None:
            borrowed = borrowed_tuning(Path(self.tuned_from), self.base, self.ranked)
            scored = borrowed[1].get("metric") or (borrowed[1].get("design") or {}).get(
                "metric", "ade_k1"
            )
            if scored != self.metric:
                raise InputError(
                    f"the tuning in {self.tuned_from} was scored on {scored}, but this board "
                    f"ranks {self.metric}: tune anew (--retune) or rank it (--metric {scored})"
                )
        object.__setattr__(self, "borrowed", borrowed)

    def _check(self) -> None:
        """One line for an option out of range, before anything runs."""
        check_metric(self.metric)
        if self.prune and self.metric != "ade_k1":
            raise InputError(
                "--prune stops trials on the point prediction's ADE; not with best of K"
            )
        if REFERENCE not in self.ranked:
            raise InputError(
                f"methods: the board tests every method against {REFERENCE}; include it"
            )
        if self.sampler not in SAMPLERS:
            raise InputError(f"--sampler {self.sampler!r}: expected one of {', '.join(SAMPLERS)}")
        if self.reference_seeds < 1:
            raise InputError(f"reference seeds must be at least 1, got {self.reference_seeds}")
        if self.compare:
            if len(self.compare) != 2 or len(set(self.compare)) != 2:
                raise InputError(f"--compare {','.join(self.compare)}: name two methods")
            for method in self.compare:
                if method not in self.base.methods or method in references(self.base.methods):
                    raise InputError(f"--compare: {method!r} is not a ranked method of this run")
        if not 0 < self.width <= 1:
            raise InputError(f"--width {self.width:g}: expected metres in (0, 1]")
        if self.max_seeds < self.base.seeds:
            raise InputError(f"--max-seeds {self.max_seeds}: below --seeds {self.base.seeds}")
        if self.replay_budget is not None and self.replay_budget < 1:
            raise InputError(f"replay budget must be at least 1 scene, got {self.replay_budget}")
        if self.tune_scenario is not None:
            tuning = parse_scenario(self.tune_scenario, list(self.base.scenarios_dir))
            if len(tuning) < 3:
                raise InputError(
                    f"--tune-scenario {self.tune_scenario!r}: {len(tuning)} task(s); tuning "
                    "needs three or more, or no method's care for old tasks can matter"
                )

    def _protocol_settings(self) -> dict[str, dict[str, Any]]:
        """The user's settings over the protocol's: batch, the preset's data sizes, the equal
        replay budget, joint-scratch trained once."""
        settings = dict(self.base.settings)
        for scope, values in self.recipe.items():
            settings[scope] = {**values, **settings.get(scope, {})}
        settings["train"] = {"batch_scenes": BATCH, **settings.get("train", {})}
        if self.data:
            settings["data"] = {**self.data, **settings.get("data", {})}
        if self.replay_budget is not None:
            tasks = len(self.base.specs)
            for name in self.base.methods:
                options = get_method(name).replay_options(self.replay_budget, tasks)
                if options:
                    settings[name] = {**options, **settings.get(name, {})}
        if "joint-scratch" in self.base.methods:  # its one meaningful row: trained once
            settings["joint-scratch"] = {"final_only": True, **settings.get("joint-scratch", {})}
        return settings

    @property
    def references(self) -> tuple[str, ...]:
        return references(self.base.methods)

    @property
    def ranked(self) -> tuple[str, ...]:
        return tuple(m for m in self.base.methods if m not in self.references)

    def tuning_base(self) -> ExperimentConfig:
        """The tuning's experiment: the tuning curriculum, the ranked methods, the tuning seed."""
        first = self.base.specs[0]
        scenario = self.tune_scenario or f"{first.family.name}_{first.label}"
        settings = {s: v for s, v in self.base.settings.items() if s not in self.references}
        return replace(
            self.base,
            scenario=scenario,
            methods=self.ranked,
            settings=settings,
            seed=self.base.seed if self.tuning_seed is None else self.tuning_seed,
        )

    def tuning(self) -> TuneConfig:
        """Optuna's tuning of every ranked method, its studies named by this benchmark's key."""
        return TuneConfig(
            self.tuning_base(),
            self.trials,
            self.storage,
            self.prune,
            study_prefix=self.key(),
            race=self.race,
            race_seeds=self.race_seeds,
            sampler=self.sampler,
            metric=self.metric,
        )

    def key(self) -> str:
        """``NAME-HASH:``: the preset and a hash of everything that decides the trials (the
        tuning curriculum, sizes, settings, budget), so no shared storage mixes benchmarks. The
        race is not in it: it reads the trials, never changes them."""
        tuning = replace(self.base, scenario=self.tune_scenario or self.base.scenario)
        if self.tuning_seed is not None:
            tuning = replace(tuning, seed=self.tuning_seed)
        protocol = {
            "scenario": self.base.scenario,
            "tuning": tuning.to_json(),
            "trials": self.trials,
            "prune": self.prune,
        }
        if self.sampler != "tpe":  # the TPE-tuned boards keep their keys
            protocol["sampler"] = self.sampler
        if self.design is not None:
            protocol["design"] = self.design.to_json()
        if self.metric != "ade_k1":  # the point-prediction boards keep their keys
            protocol["metric"] = self.metric
        text = json.dumps(protocol, sort_keys=True, default=str)
        return f"{self.name}-{hashlib.sha256(text.encode()).hexdigest()[:12]}:"

    def sizes(self) -> str:
        """``quick``, ``reduced`` (any size below the protocol's) or ``protocol``."""
        if self.base.quick:
            return "quick"
        full = ExperimentConfig(  # the default sizes; a family of --scenarios-dir found
            self.base.scenario, self.base.methods[:1], scenarios_dir=self.base.scenarios_dir
        )
        train = self.base.settings.get("train", {})
        smaller = (
            self.base.epochs < full.epochs
            or self.base.k < full.k
            or self.base.seeds < SEEDS
            or self.trials < TRIALS
            or self.reference_seeds < REFERENCE_SEEDS
            or train.get("batch_scenes", BATCH) != BATCH
        )
        return "reduced" if smaller else "protocol"

    def to_json(self) -> dict[str, Any]:
        """What a resumed benchmark must share with the one it continues (the decisive pair may
        be added or changed on a resume: it only adds seeds to two methods)."""
        return {
            "base": self.base.to_json(),
            "name": self.name,
            "tune_scenario": self.tune_scenario,
            "trials": self.trials,
            "replay_budget": self.replay_budget,
            "prune": self.prune,
            "reference_seeds": self.reference_seeds,
            "storage": self.storage,
            "data": self.data,
            **({} if self.tuning_seed is None else {"tuning_seed": self.tuning_seed}),
            **({"race": self.race, "race_seeds": self.race_seeds} if self.race else {}),
            **({} if self.sampler == "tpe" else {"sampler": self.sampler}),
            **({"tuned_from": self.borrowed[1]["sha256"]} if self.borrowed else {}),
            **({"design": self.design.to_json()} if self.design else {}),
            **({} if self.metric == "ade_k1" else {"metric": self.metric}),
            **({"recipe": self.recipe} if self.recipe else {}),
        }


def seed_count(bench: BenchConfig, method: str) -> int:
    """The seeds a method is evaluated on before the decisive pair's extra ones."""
    if method in references(bench.base.methods):
        return min(bench.reference_seeds, bench.base.seeds)
    return bench.base.seeds
