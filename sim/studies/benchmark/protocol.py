"""The fair benchmark: tune every method with the same budget, evaluate it over seeds that each
draw their own data, and rank the methods with intervals and Holm-corrected paired tests.

The protocol (``docs/benchmark.md``): batch 16 and every method's learning rate tuned; the same
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

from c2inet.files import write_text_atomic
from c2inet.report import REFERENCE, summarise
from c2inet.significance import seeds_to_narrow
from sim.experiment.backends import kept_workers
from sim.experiment.config import Execution, ExperimentConfig
from sim.experiment.folders import MARKER, claim, mark_run, record_written
from sim.experiment.jobs import JobResult, prepare
from sim.experiment.outputs import COLUMNS, git_commit, tidy_rows, write_report, write_results
from sim.experiment.staged import run_staged
from sim.experiment.storage import check_storage
from sim.experiment.sweep import layered, plan, run_together
from sim.experiment.trials import trial_paths, trial_results, trial_seconds
from sim.experiment.tuning import run_tuning
from sim.studies.benchmark.artefacts import write_artefact
from sim.studies.benchmark.board_markdown import leaderboard_markdown
from sim.studies.benchmark.config import LEAN, BenchConfig, references, seed_count
from sim.studies.benchmark.estimate import estimate_bench, estimate_line
from sim.studies.benchmark.leaderboard import leaderboard
from viz.loggers import prepare_tracking
from viz.study_figures import leaderboard_figure


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
        a, b = (self.summary(m)[f"final_{self.bench.metric}_per_seed"] for m in pair)
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


def what_ran(bench: BenchConfig, execution: Execution, argv: list[str] | None) -> dict:
    """The board's sizes, ``--set``, machine, jobs, backend and command."""
    return {
        "sizes": bench.sizes(),
        "settings": bench.given,
        "machine": machine(),
        "jobs": execution.jobs,
        "backend": execution.backend,
        **({"ray_address": execution.ray_address} if execution.ray_address else {}),
        "command": " ".join(argv or []),
    }


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


def tune(bench: BenchConfig, out: Path, execution: Execution) -> dict[str, dict[str, Any]]:
    """Every ranked method's settings: a shipped tuning or another benchmark's (nothing to
    tune here), or a tuning by the staged design or by Optuna's trials."""
    if bench.borrowed:
        return bench.borrowed[0]
    if bench.design is not None:
        return run_staged(
            bench.tuning_base(), bench.design, out / "tuning", execution, bench.metric
        )
    return run_tuning(bench.tuning(), out / "tuning", execution)


def tuning_runs(bench: BenchConfig, out: Path) -> int:
    """How many tuning runs of the ranked methods have finished under ``out`` (counted, not
    read: a tuning holds hundreds)."""
    return sum(len(trial_paths(out / "tuning", m)) for m in bench.ranked)


def record_tuning_call(
    bench: BenchConfig, out: Path, commit, started: float, runs_before: int
) -> list[dict[str, Any]]:
    """Add this call's commit, wall seconds since ``started`` and tuning runs beyond
    ``runs_before`` to ``tuning/calls.json`` and return every call's: a resumed tuning's artefact
    names each commit that ran part of it (and the one that chose), not only the last call's."""
    path = out / "tuning" / "calls.json"
    calls = json.loads(path.read_text()) if path.is_file() else []
    wall, runs = time.perf_counter() - started, tuning_runs(bench, out) - runs_before
    calls.append({"commit": commit, "wall_seconds": round(wall, 1), "runs": runs})
    path.parent.mkdir(parents=True, exist_ok=True)
    write_text_atomic(path, json.dumps(calls, indent=1) + "\n")
    return calls


def write_tuning_artefact(
    bench: BenchConfig, out: Path, chosen: dict, calls: list[dict[str, Any]], argv
) -> dict[str, Any]:
    """The tuning as a shipped artefact (``artefacts.py``): every method's choice with the
    curricula, design, seed, runs, commits, machine and cost that produced it (``calls``: the
    calls of ``record_tuning_call``, this one last)."""
    base = bench.tuning_base()
    cpu = sum(
        r.get("cpu_seconds") or 0.0 for m in bench.ranked for r in trial_results(out / "tuning", m)
    )
    provenance = {
        "made_by": " ".join(argv or []),
        "commits": list(dict.fromkeys(c["commit"] for c in calls)),
        "calls": calls,
        "machine": machine(),
        "cpu_seconds": round(cpu, 1),
        "wall_seconds": round(sum(c["wall_seconds"] for c in calls), 1),
        "epochs": bench.base.epochs,
        "batch_scenes": bench.base.train_config().batch_scenes,
        "data": bench.base.settings.get("data", {}),
        "key": bench.key(),
    }
    design = (
        bench.design.to_json()
        if bench.design is not None
        else {
            "kind": "optuna",
            "sampler": bench.sampler,
            "trials": bench.trials,
            "race": bench.race,
            "prune": bench.prune,
            "draws": 1,
        }  # fmt: skip
    )
    if bench.metric != "ade_k1":  # what its runs were scored by, where not the point prediction
        design = {**design, "metric": bench.metric}
    path = out / f"{bench.name}.json"
    methods = {m: chosen[m] for m in bench.ranked}
    if path.is_file():  # a resumed board: the artefact of the tuning it finished stays as made
        made = json.loads(path.read_text())
        if made.get("methods") == json.loads(json.dumps(methods)):
            return made
    record_written(out, [path.name])  # ours, for --overwrite, before it is written
    artefact = write_artefact(
        path, bench.name, bench.base.scenario, base.scenario, design, base.seed, provenance,
        methods,
    )  # fmt: skip
    print(
        f"the tuning artefact: {path} (ship it as sim/studies/benchmark/tunings/{bench.name}.json)",
        file=sys.stderr,
    )
    return artefact


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
    tune_only: bool = False,
) -> dict[str, Any]:
    """Tune, evaluate and rank; returns the leaderboard (also written under ``out``). With
    ``tune_only``, tune and write the tuning artefact (``out/PRESET.json``, the file a preset
    ships) and stop; returns the artefact."""
    # every trial and evaluation run of the benchmark in one tracking experiment (--logger)
    execution = replace(execution or Execution(), tracking=out)
    started, cpu_started = time.perf_counter(), time.process_time()
    commit = git_commit()  # the code that runs, not what the checkout holds when it ends
    check_storage(bench.storage)  # before the folder is claimed
    claim(out, bench, execution, resume, overwrite)
    prepare_tracking(execution.loggers, out)
    estimate = None
    if not resume and not bench.base.quick and bench.design is None and not tune_only:
        # (a quick benchmark costs as much as its timing; the estimate counts Optuna's trials)
        cost = estimate_bench(bench, execution)
        estimate = {k: round(cost[k], 1) for k in ("cpu_seconds", "wall_seconds")}
        print(estimate_line(cost, execution.jobs), file=sys.stderr)
    with kept_workers():  # the tuning rounds and the evaluation start the workers once
        runs_before = tuning_runs(bench, out)
        chosen = tune(bench, out, execution)
        if not bench.borrowed:  # what it tuned, as the file a preset ships
            calls = record_tuning_call(bench, out, commit, started, runs_before)
            artefact = write_tuning_artefact(bench, out, chosen, calls, argv)
            if tune_only:
                return artefact
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
        **what_ran(bench, execution, argv),
        **calls,
        "cpu_seconds": round(measured_cpu(out, evaluation), 1),
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
