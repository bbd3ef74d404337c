"""The fair benchmark: tune every method with the same budget, evaluate it over seeds that each
draw their own data, and rank the methods with intervals and Holm-corrected paired tests.

The protocol (``docs/benchmark.md``): batch 64 and every method's learning rate tuned; the same
number of Optuna trials for every method, on a tuning curriculum of at least three tasks that
shares no value with the evaluated one, scored on validation data only; then every method with
its chosen settings over ``seeds`` seeds, seed s generating its own domains (the same for every
method: the comparison is paired); equal replay budgets; the references (joint, joint from
scratch) on fewer seeds with fine-tuning's settings, shown apart and never ranked. A decisive pair
(``compare``) gets more seeds until the 95 % interval of its paired difference is narrower than
``width`` or it has ``max_seeds``.

A benchmark folder holds ``tuning/`` (the Optuna studies and their trials, ``tuning.json``),
``evaluation/METHOD/seed_S/`` (one ordinary one-seed run each, lean: no figures, validation
curves, diagnostics or unseen tasks) and the leaderboard: ``leaderboard.md``,
``leaderboard.json``, ``results.parquet`` (every matrix cell, tidy) and ``leaderboard.png``.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import platform
import sys
import time
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
import torch

from c2inet.errors import InputError
from c2inet.files import write_text_atomic
from c2inet.methods.base import get_method
from c2inet.report import REFERENCE, summarise
from c2inet.significance import seeds_to_narrow
from sim.experiment.backends import kept_workers
from sim.experiment.config import Execution, ExperimentConfig
from sim.experiment.estimate import describe, job_seconds, lanes_seconds
from sim.experiment.folders import MARKER, claim, mark_run
from sim.experiment.jobs import JobResult, prepare
from sim.experiment.outputs import COLUMNS, git_commit, tidy_rows, write_report, write_results
from sim.experiment.sweep import layered, plan, run_together
from sim.experiment.tuning import (
    TRIAL_TRAIN,
    TuneConfig,
    check_storage,
    run_tuning,
    search_space,
    trial_results,
    trial_seconds,
    validation_inputs,
)
from sim.scenario import parse_scenario
from sim.studies.leaderboard import leaderboard, leaderboard_markdown
from sim.studies.presets import (  # noqa: F401  (the protocol, exported with the run)
    BATCH,
    PRESETS,
    REFERENCE_SEEDS,
    REPLAY_BUDGET,
    SEEDS,
    TRIALS,
    Preset,
)
from viz.study_figures import leaderboard_figure

# what the leaderboard never reads, so evaluation jobs skip it (as tuning trials do)
LEAN = TRIAL_TRAIN


def references(methods: tuple[str, ...]) -> tuple[str, ...]:
    """The methods that are references, not competitors: those that see old tasks' data."""
    return tuple(m for m in methods if get_method(m).sees_old_tasks)


@dataclass(frozen=True)
class BenchConfig:
    """``base``: the evaluation (scenario, methods, ``seeds`` of every ranked method, sizes,
    ``--set``; the protocol's batch unless ``--set train.batch_scenes``); ``name``: the preset
    (or ``custom``); ``tune_scenario``: the tuning curriculum; ``trials`` per method; ``prune``:
    stop trials worse than the median so far; ``replay_budget``: scenes every replay method
    keeps (None: each its own default); ``reference_seeds``; ``compare``: the decisive pair,
    given seeds until its interval is narrower than ``width`` metres or it has ``max_seeds``;
    ``data``: the preset's data sizes (``Preset.data``), under the user's own ``--set data.*``;
    ``tuning_seed``: the tuning's root seed (its sampler, trials and data) where it is not the
    evaluation's, so two tunings of one benchmark can be compared on the same evaluation."""

    base: ExperimentConfig
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
    given: dict[str, Any] = field(init=False, compare=False, repr=False)  # the user's --set

    def __post_init__(self):
        object.__setattr__(self, "compare", tuple(self.compare))
        object.__setattr__(self, "given", self.base.settings)
        if REFERENCE not in self.ranked:
            raise InputError(
                f"methods: the board tests every method against {REFERENCE}; include it"
            )
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
        if self.tune_scenario is not None:
            tuning = parse_scenario(self.tune_scenario, list(self.base.scenarios_dir))
            if len(tuning) < 3:
                raise InputError(
                    f"--tune-scenario {self.tune_scenario!r}: {len(tuning)} task(s); tuning "
                    "needs three or more, or no method's care for old tasks can matter"
                )
        settings = dict(self.base.settings)
        settings["train"] = {"batch_scenes": BATCH, **settings.get("train", {})}
        if self.data:
            settings["data"] = {**self.data, **settings.get("data", {})}
        if self.replay_budget is not None:
            if self.replay_budget < 1:
                raise InputError(
                    f"replay budget must be at least 1 scene, got {self.replay_budget}"
                )
            tasks = len(self.base.specs)
            for name in self.base.methods:
                options = get_method(name).replay_options(self.replay_budget, tasks)
                if options:
                    settings[name] = {**options, **settings.get(name, {})}
        if "joint-scratch" in self.base.methods:  # its one meaningful row: trained once
            settings["joint-scratch"] = {"final_only": True, **settings.get("joint-scratch", {})}
        object.__setattr__(self, "base", replace(self.base, settings=settings))

    @property
    def references(self) -> tuple[str, ...]:
        return references(self.base.methods)

    @property
    def ranked(self) -> tuple[str, ...]:
        return tuple(m for m in self.base.methods if m not in self.references)

    def tuning(self) -> TuneConfig:
        """The tuning of every ranked method, its studies named by this benchmark's key."""
        first = self.base.specs[0]
        scenario = self.tune_scenario or f"{first.family.name}_{first.label}"
        settings = {s: v for s, v in self.base.settings.items() if s not in self.references}
        base = replace(
            self.base,
            scenario=scenario,
            methods=self.ranked,
            settings=settings,
            seed=self.base.seed if self.tuning_seed is None else self.tuning_seed,
        )
        return TuneConfig(base, self.trials, self.storage, self.prune, study_prefix=self.key())

    def key(self) -> str:
        """``NAME-HASH:``: the preset and a hash of everything that decides the trials (the
        tuning curriculum, sizes, settings, budget), so no shared storage mixes benchmarks."""
        tuning = replace(self.base, scenario=self.tune_scenario or self.base.scenario)
        if self.tuning_seed is not None:
            tuning = replace(tuning, seed=self.tuning_seed)
        protocol = {
            "scenario": self.base.scenario,
            "tuning": tuning.to_json(),
            "trials": self.trials,
            "prune": self.prune,
        }
        text = json.dumps(protocol, sort_keys=True, default=str)
        return f"{self.name}-{hashlib.sha256(text.encode()).hexdigest()[:12]}:"

    def sizes(self) -> str:
        """``quick``, ``reduced`` (any size below the protocol's) or ``protocol``."""
        if self.base.quick:
            return "quick"
        full = ExperimentConfig(self.base.scenario, self.base.methods[:1])
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
        }


def estimate_bench(bench: BenchConfig, execution: Execution) -> dict[str, Any]:
    """What a benchmark will cost, by the run's own estimate (``sim.experiment.estimate``, in
    CPU seconds of one thread): one tuning trial (``trial``) and one evaluation job (``job``) of
    each method; the trials each method gets; the CPU seconds of all of them, of the tuning
    alone, and the wall time with ``execution.jobs`` at a time (the tuning's rounds hold a trial
    of every method, so it is shared out evenly; the evaluation's jobs go longest first). The
    decisive pair's extra seeds are not counted: how many it needs is known only after."""
    torch.set_num_threads(execution.threads)
    tuning = bench.tuning().base
    tuning = replace(tuning, settings=layered(tuning, {"train": TRIAL_TRAIN}), record=False)
    evaluation = replace(bench.base, settings=layered(bench.base, {"train": LEAN}), record=False)
    trial = job_seconds(tuning, validation_inputs(prepare(tuning, execution)).tasks)
    job = job_seconds(evaluation, prepare(evaluation, execution).inputs.tasks)
    trials = {m: bench.trials if search_space(m) else 0 for m in bench.ranked}
    tuning_cpu = sum(trials[m] * trial[m] for m in bench.ranked)
    seeds = {m: seed_count(bench, m) for m in bench.base.methods}
    evaluation_cpu = sum(seeds[m] * job[m] for m in bench.base.methods)
    jobs = [job[m] for m in bench.base.methods for _ in range(seeds[m])]
    return {
        "trial": trial,
        "job": job,
        "trials": trials,
        "seeds": seeds,
        "cpu_seconds": tuning_cpu + evaluation_cpu,
        "tuning_cpu_seconds": tuning_cpu,
        "wall_seconds": tuning_cpu / execution.jobs + lanes_seconds(jobs, execution.jobs),
        "jobs": execution.jobs,
    }


def estimate_line(cost: dict[str, Any], jobs: int) -> str:
    """The estimate in one line, as a board prints it before it starts."""
    return (
        f"{sum(cost['trials'].values())} tuning trials and {sum(cost['seeds'].values())} "
        f"evaluation jobs, {jobs} at a time: about {describe(cost['wall_seconds'])} "
        f"({cost['cpu_seconds']:.0f} CPU s, timed on this machine)"
    )


def estimate_table(bench: BenchConfig, cost: dict[str, Any]) -> str:
    """``sim.bench --estimate``: each method's CPU seconds a trial and a job, its trials and
    seeds, and what they add up to, so a preset can be sized before it runs."""
    rows = ["| method | trial (CPU s) | trials | job (CPU s) | seeds | in all (CPU s) |"]
    rows.append("|---|---|---|---|---|---|")
    for m in bench.base.methods:
        trials, seeds = cost["trials"].get(m, 0), cost["seeds"][m]
        spent = trials * cost["trial"].get(m, 0.0) + seeds * cost["job"][m]
        trial = f"{cost['trial'][m]:.1f}" if trials else "-"  # untuned, or a reference
        rows.append(f"| {m} | {trial} | {trials} | {cost['job'][m]:.1f} | {seeds} | {spent:.0f} |")
    return "\n".join(rows) + f"\n\n{bench.name}: " + estimate_line(cost, cost["jobs"])


def seed_count(bench: BenchConfig, method: str) -> int:
    """The seeds a method is evaluated on before the decisive pair's extra ones."""
    if method in references(bench.base.methods):
        return min(bench.reference_seeds, bench.base.seeds)
    return bench.base.seeds


@dataclass
class Evaluation:
    """The evaluation's one-seed runs: each seed's curriculum (prepared once, every method's),
    and every finished job by method, in seed order."""

    bench: BenchConfig
    out: Path
    execution: Execution
    chosen: dict[str, dict[str, Any]]
    argv: list[str]
    curricula: dict[int, Any] = field(default_factory=dict)
    done: dict[str, list[tuple[ExperimentConfig, JobResult]]] = field(default_factory=dict)

    def config(self, method: str, seed: int) -> ExperimentConfig:
        """Seed ``seed``'s one-seed run of ``method``: its own data and training seed, the
        tuned settings (fine-tuning's for a reference), lean."""
        base = self.bench.base
        tuned_as = REFERENCE if method in references(base.methods) else method
        tuned = self.chosen.get(tuned_as, {}).get("settings", {})
        settings = layered(base, {**tuned, "train": {**tuned.get("train", {}), **LEAN}})
        return replace(base.only(method, settings), seeds=1, seed=base.seed + seed, record=False)

    def run(self, wanted: dict[str, int]) -> None:
        """Run every method up to ``wanted[method]`` seeds (those already done are read back)."""
        planned, costs = [], []
        for method, count in wanted.items():
            for seed in range(len(self.done.get(method, [])), count):
                config = self.config(method, seed)
                if seed not in self.curricula:
                    self.curricula[seed] = prepare(config, self.execution)
                folder = self.out / "evaluation" / method / f"seed_{seed}"
                resumed = (folder / "config.json").is_file()
                label = f"{method} seed {seed}"
                curriculum = self.curricula[seed]
                planned.append(plan(label, config, folder, self.execution, resumed, curriculum))
                # the longest first: by the method's tuning trials; the references, untuned and
                # the longest (joint's data grows), before all
                reference = method in self.bench.references
                costs.append(math.inf if reference else trial_seconds(self.out / "tuning", method))
        if not planned:
            return
        results = run_together(
            planned, self.execution, resume=True, argv=self.argv, costs=costs, figures=False
        )
        for (_, config, *_), (_, (job,)) in zip(planned, results, strict=True):
            self.done.setdefault(config.methods[0], []).append((config, job))

    def summary(self, method: str, seeds: int | None = None) -> dict[str, Any]:
        """:func:`c2inet.report.summarise` of ``method``'s first ``seeds`` seeds (all: None),
        with its mean CPU seconds a job."""
        jobs = [job for _, job in self.done[method][:seeds]]
        summary = summarise([j.result.matrices for j in jobs], [j.result.summaries for j in jobs])
        summary["cpu_seconds"] = float(np.mean([j.cpu_seconds or 0.0 for j in jobs]))
        return summary

    def differences(self, pair: tuple[str, str]) -> list[float]:
        """The paired differences of final point-prediction ADE, first minus second, per seed
        both have."""
        a, b = (self.summary(m)["final_ade_k1_per_seed"] for m in pair)
        return [x - y for x, y in zip(a, b, strict=False)]


def machine() -> str:
    """The processor and its cores, as a board names where it ran."""
    model = platform.processor() or platform.machine()
    cpuinfo = Path("/proc/cpuinfo")
    if cpuinfo.is_file():
        names = [
            line.split(":", 1)[1].strip()
            for line in cpuinfo.read_text().splitlines()
            if line.startswith("model name")
        ]
        model = names[0] if names else model
    return f"{model}, {os.cpu_count()} cores ({platform.system()})"


def measured_cpu(out: Path, evaluation: Evaluation) -> float:
    """The CPU seconds every tuning trial and evaluation job took (those of a killed and
    resumed job: its last part)."""
    tuning = sum(
        r.get("cpu_seconds") or 0.0
        for m in evaluation.bench.ranked
        for r in trial_results(out / "tuning", m)
    )
    jobs = sum(job.cpu_seconds or 0.0 for done in evaluation.done.values() for _, job in done)
    return tuning + jobs


def record_call(out: Path, wall: float, decisive: float, estimate, commit) -> dict[str, Any]:
    """Add this call to ``spent.json`` and return the totals: wall seconds, calls, the decisive
    pair's seconds (apart: the board's own time is the rest), the first call's estimate (made
    before it began) and the commits that ran."""
    spent = {"wall_seconds": 0, "calls": 0, "decisive_seconds": 0, "estimate": None, "commits": []}
    if (out / "spent.json").is_file():
        spent |= json.loads((out / "spent.json").read_text())
    spent = {
        "wall_seconds": round(spent["wall_seconds"] + wall, 1),
        "calls": spent["calls"] + 1,
        "decisive_seconds": round(spent["decisive_seconds"] + decisive, 1),
        "estimate": spent["estimate"] or estimate,
        "commits": list(dict.fromkeys([*spent["commits"], commit])),
    }
    write_text_atomic(out / "spent.json", json.dumps(spent) + "\n")
    return spent


def decide_pair(bench: BenchConfig, evaluation: Evaluation) -> dict[str, Any] | None:
    """Give the decisive pair seeds until its interval is narrow or it has the most; returns
    both methods' summaries over all their seeds (None without a pair)."""
    if not bench.compare:
        return None
    while True:
        differences = evaluation.differences(bench.compare)
        needed = seeds_to_narrow(differences, bench.width, bench.max_seeds)
        if needed <= len(differences):
            return {m: evaluation.summary(m) for m in bench.compare}
        evaluation.run(dict.fromkeys(bench.compare, needed))


def run_bench(
    bench: BenchConfig,
    out: Path,
    execution: Execution | None = None,
    resume: bool = False,
    overwrite: bool = False,
    argv: list[str] | None = None,
) -> dict[str, Any]:
    """Tune, evaluate and rank; returns the leaderboard (also written under ``out``)."""
    execution = execution or Execution()
    started, cpu_started = time.perf_counter(), time.process_time()
    commit = git_commit()  # the code that runs, not what the checkout holds when it ends
    check_storage(bench.storage)  # before the folder is claimed
    claim(out, bench, execution, resume, overwrite)
    estimate = None
    if not resume and not bench.base.quick:  # timing a quick benchmark costs as much as running it
        cost = estimate_bench(bench, execution)
        estimate = {k: round(cost[k], 1) for k in ("cpu_seconds", "wall_seconds")}
        print(estimate_line(cost, execution.jobs), file=sys.stderr)
    with kept_workers():  # the tuning rounds and the evaluation start the workers once
        chosen = run_tuning(bench.tuning(), out / "tuning", execution)
        (out / "evaluation").mkdir(exist_ok=True)
        if not (out / "evaluation" / MARKER).is_file():  # a folder of ours, for --overwrite
            mark_run(out / "evaluation")
        evaluation = Evaluation(bench, out, execution, chosen, argv or [])
        evaluation.run({m: seed_count(bench, m) for m in bench.base.methods})
        decisive_started = time.perf_counter()
        decisive = decide_pair(bench, evaluation)
        decisive_spent = time.perf_counter() - decisive_started
    summaries = {m: evaluation.summary(m, seed_count(bench, m)) for m in bench.base.methods}
    wall = time.perf_counter() - started
    calls = record_call(out, wall, decisive_spent, estimate, commit)
    run = {
        "sizes": bench.sizes(),
        "settings": bench.given,
        "machine": machine(),
        "jobs": execution.jobs,
        **calls,
        "cpu_seconds": round(measured_cpu(out, evaluation), 1),
        "command": " ".join(argv or []),
        "cpu_seconds_driver": round(time.process_time() - cpu_started, 1),
    }
    board = leaderboard(bench, summaries, chosen, decisive, run)
    rows = {c: [] for c in COLUMNS}
    for jobs in evaluation.done.values():
        for config, job in jobs:
            for column, values in tidy_rows("tuned", config, [job]).items():
                rows[column] += values
    write_results(out / "results.parquet", rows)
    write_report(out, "leaderboard", board, leaderboard_markdown, leaderboard_figure)
    return board
