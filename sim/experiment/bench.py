"""The fair benchmark: tune every method with the same budget, then evaluate it over seeds and
rank the methods with intervals and paired tests.

A benchmark folder holds ``tuning/`` (the Optuna studies and their trials, ``tuning.json``),
``evaluation/METHOD/`` (one ordinary run per method with its chosen settings, on the same
seeds and the same data as every other method) and the leaderboard: ``leaderboard.md``,
``leaderboard.json``, ``results.parquet`` (every matrix cell, tidy) and ``leaderboard.png``.
"""

from __future__ import annotations

import json
import sys
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
import torch

from c2inet.errors import InputError
from c2inet.files import write_text_atomic
from c2inet.methods.base import get_method
from c2inet.report import REFERENCE, compare, comparison_rows, markdown_table
from c2inet.significance import ALPHA
from sim.experiment.backends import kept_workers
from sim.experiment.config import Execution, ExperimentConfig
from sim.experiment.estimate import describe, job_seconds, run_seconds
from sim.experiment.jobs import prepare
from sim.experiment.outputs import COLUMNS, claim, tidy_rows, write_results
from sim.experiment.sweep import layered, plan, run_together
from sim.experiment.tuning import (
    TRIAL_TRAIN,
    TuneConfig,
    run_tuning,
    search_space,
    trial_seconds,
    validation_inputs,
)
from viz.figures import leaderboard_figure


@dataclass(frozen=True)
class Preset:
    """A benchmark's curriculum, the separate curriculum its methods are tuned on (None: the
    first task's validation data), and what it stands for."""

    scenario: str
    tune_scenario: str | None
    description: str


PRESETS = {
    "radius": Preset(
        "crowd_radius_0.1..0.6",
        "crowd_radius_0.15..0.55:0.2",
        "the paper's Table 2 on the ORCA-steered crowd_radius; tuned on radii between its own",
    ),
    "density": Preset(
        "crowd_density_0.05..0.30:0.05",
        "crowd_density_0.075..0.275:0.1",
        "crowd density, where the domain is visible in the past; tuned on densities between",
    ),
    "noise": Preset(
        "crowd_noise_0.1..0.6",
        "crowd_noise_0.15..0.55:0.2",
        "behavioural noise of Pymunk crowds; tuned on noise levels between its own",
    ),
    "eth-ucy": Preset(
        "eth_ucy_univ,eth,zara1,zara2,hotel",
        None,
        "the ETH-UCY stream, one scene a task; tuned on univ's held-out training scenes",
    ),
    "traffic": Preset(
        "highway_density_0.5..2.0:0.5",
        None,
        "highway-env traffic density; tuned on the first density's validation split",
    ),
}


@dataclass(frozen=True)
class BenchConfig:
    """``base``: the evaluation (scenario, methods, seeds, sizes, ``--set``); ``tune_scenario``:
    the tuning curriculum (None: the first task of ``base.scenario``); ``trials`` per method;
    ``prune``: stop trials worse than the median so far (``sim.experiment.tuning``)."""

    base: ExperimentConfig
    tune_scenario: str | None = None
    trials: int = 6
    storage: str | None = None
    replay_budget: int | None = None  # scenes every replay method keeps in all (None: defaults)
    prune: bool = False

    def __post_init__(self):
        if self.replay_budget is None:
            return
        if self.replay_budget < 1:
            raise InputError(f"replay budget must be at least 1 scene, got {self.replay_budget}")
        tasks = len(self.base.specs)
        settings = dict(self.base.settings)
        for name in self.base.methods:
            options = get_method(name).replay_options(self.replay_budget, tasks)
            if options:
                settings[name] = {**settings.get(name, {}), **options}
        object.__setattr__(self, "base", replace(self.base, settings=settings))

    def tuning(self) -> TuneConfig:
        first = self.base.specs[0]
        scenario = self.tune_scenario or f"{first.family.name}_{first.label}"
        base = replace(self.base, scenario=scenario)
        return TuneConfig(base, self.trials, self.storage, self.prune)

    def to_json(self) -> dict[str, Any]:
        return {
            "base": self.base.to_json(),
            "tune_scenario": self.tune_scenario,
            "trials": self.trials,
            "replay_budget": self.replay_budget,
            "prune": self.prune,
        }


def estimate_bench(bench: BenchConfig, execution: Execution) -> dict[str, Any]:
    """What a benchmark will cost, by the run's own estimate (``sim.experiment.estimate``): one
    tuning trial (``trial``) and one evaluation job (``job``) of each method, in seconds on this
    machine; the trials each method gets; the CPU seconds of all of them, of the tuning alone,
    and the wall time with ``execution.jobs`` at a time (the tuning's rounds hold a trial of
    every method, so it is shared out evenly; the evaluation's jobs go longest first)."""
    torch.set_num_threads(execution.threads)
    base, tuning = replace(bench.base, record=False), bench.tuning().base  # nothing drawn
    tuning = replace(tuning, settings=layered(tuning, {"train": TRIAL_TRAIN}), record=False)
    trial = job_seconds(tuning, validation_inputs(prepare(tuning, execution)).tasks)
    job = job_seconds(base, prepare(base, execution).inputs.tasks)
    trials = {m: bench.trials if search_space(m) else 0 for m in base.methods}
    tuning_cpu = sum(trials[m] * trial[m] for m in base.methods)
    evaluation_cpu = sum(base.seeds * job[m] for m in base.methods)
    return {
        "trial": trial,
        "job": job,
        "trials": trials,
        "cpu_seconds": tuning_cpu + evaluation_cpu,
        "tuning_cpu_seconds": tuning_cpu,
        "wall_seconds": tuning_cpu / execution.jobs + run_seconds(base, job, execution.jobs),
    }


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
    claim(out, bench, execution, resume, overwrite)
    if not resume and not bench.base.quick:  # timing a quick benchmark costs as much as running it
        cost = estimate_bench(bench, execution)
        trials = sum(cost["trials"].values())
        print(
            f"{trials} tuning trials and {len(bench.base.jobs())} evaluation jobs, "
            f"{execution.jobs} at a time: about {describe(cost['wall_seconds'])} "
            "(timed on this machine)",
            file=sys.stderr,
        )
    with kept_workers():  # the tuning rounds and the evaluation start the workers once
        chosen = run_tuning(bench.tuning(), out / "tuning", execution)
        planned = []
        for method in bench.base.methods:
            settings = layered(bench.base, chosen[method]["settings"])
            config = replace(bench.base, methods=(method,), settings=settings)
            folder = out / "evaluation" / method
            resumed = (folder / "config.json").is_file()
            planned.append(plan(method, config, folder, execution, resumed))
        costs = [trial_seconds(out / "tuning", m) for m in bench.base.methods]  # longest first
        done = run_together(planned, execution, resume=True, argv=argv or [], costs=costs)
    names = bench.base.methods
    methods = {m: metrics["methods"][m] for m, (metrics, _) in zip(names, done, strict=True)}
    cost = {
        m: float(np.mean([r.cpu_seconds or 0.0 for r in results]))
        for m, (_, results) in zip(names, done, strict=True)
    }
    board = leaderboard(bench, methods, chosen, cost)
    rows = {c: [] for c in COLUMNS}
    for (_, config, *_), (_, results) in zip(planned, done, strict=True):
        for column, values in tidy_rows("tuned", config, results).items():
            rows[column] += values
    write_results(out / "results.parquet", rows)
    write_text_atomic(out / "leaderboard.json", json.dumps(board, indent=1) + "\n")
    write_text_atomic(out / "leaderboard.md", leaderboard_markdown(board))
    leaderboard_figure(board, out / "leaderboard.png")
    return board


def leaderboard(
    bench: BenchConfig,
    methods: dict[str, dict[str, Any]],
    chosen: dict[str, dict[str, Any]],
    cost: dict[str, float],
) -> dict[str, Any]:
    """Every method and test-time rule ranked by its final point-prediction ADE, with its
    interval, the paired test against the reference, forgetting, memory, CPU cost and the
    settings tuning chose."""
    comparison = compare(methods)
    ranked = sorted(comparison, key=lambda name: comparison[name]["final_ade_k1"]["mean"])
    entries = []
    for rank, name in enumerate(ranked, 1):
        method = name.split(",")[0]
        entries.append(
            {
                "rank": rank,
                "method": name,
                **comparison[name],
                "cpu_seconds": round(cost[method], 1),
                "settings": chosen[method]["settings"],
                "trials": len(chosen[method]["trials"]),
                "pruned": sum(t["pruned"] for t in chosen[method]["trials"]),
            }
        )
    base = bench.base
    return {
        "scenario": base.scenario,
        "tune_scenario": bench.tuning().base.scenario,
        "trials": bench.trials,
        "prune": bench.prune,
        "replay_budget": bench.replay_budget,
        "seeds": base.seeds,
        "quick": base.quick,
        "reference": REFERENCE,
        "alpha": ALPHA,
        "entries": entries,
    }


def leaderboard_markdown(board: dict[str, Any]) -> str:
    """The leaderboard as Markdown: the ranking on the point prediction, then best of K."""
    comparison = {e["method"]: e for e in board["entries"]}
    ranked = comparison_rows(comparison, "ade_k1")  # the entries are in rank order
    ranks = ["rank", *(str(e["rank"]) for e in board["entries"])]
    by_best_of_k = dict(sorted(comparison.items(), key=lambda item: item[1]["final_ade"]["mean"]))
    settings = [["method", "chosen settings", "trials", "CPU s / job"]]
    for e in board["entries"]:
        if ", c from" in e["method"]:
            continue
        text = "; ".join(
            f"{scope}.{k}={v:.3g}" if isinstance(v, float) else f"{scope}.{k}={v}"
            for scope, options in e["settings"].items()
            for k, v in options.items()
        )
        trials = f"{e['trials']} ({e['pruned']} pruned)" if e.get("pruned") else str(e["trials"])
        cells = [text or "(nothing to tune)", trials, str(e["cpu_seconds"])]
        settings.append([e["method"], *cells])
    kind = "quick sizes (a smoke test, not a result)" if board["quick"] else "default sizes"
    pruned = ", those worse than the median so far stopped early" if board.get("prune") else ""
    return "\n".join(
        [
            f"# Benchmark: `{board['scenario']}`",
            "",
            f"Every method tuned with the same budget ({board['trials']} Optuna trials, its "
            f"defaults first{pruned}) on `{board['tune_scenario']}` scored on validation data "
            f"only, then run with the chosen settings over {board['seeds']} seeds; {kind}. Ranked "
            "by final average ADE of the point prediction (K = 1: the mean of sampled futures). "
            f"Intervals are 95 %; p is a paired t-test against {board['reference']} over the same "
            f"seeds, `*` below {board['alpha']}; a difference whose interval holds 0 is within the "
            "seed spread. Memory: floats a method keeps between tasks besides the model."
            + (
                f" Every replay method keeps {board['replay_budget']} scenes in all."
                if board.get("replay_budget")
                else ""
            ),
            "",
            "Point prediction (K = 1):",
            "",
            markdown_table([[rank, *row] for rank, row in zip(ranks, ranked, strict=True)]),
            "",
            "Best of K (ordered by its own final average):",
            "",
            markdown_table(comparison_rows(by_best_of_k, "ade")),
            "",
            "Chosen settings and cost:",
            "",
            markdown_table(settings),
            "",
        ]
    )
