"""What a benchmark will cost before it runs (``sim.bench --estimate``, and the line a board
prints as it starts), timed on this machine by ``sim.experiment.estimate``."""

from __future__ import annotations

import time
from dataclasses import replace
from typing import Any

import torch

from sim.experiment.config import Execution
from sim.experiment.curriculum import is_cached
from sim.experiment.estimate import describe, job_seconds, lanes_seconds
from sim.experiment.jobs import prepare
from sim.experiment.race import race_seed
from sim.experiment.sweep import layered
from sim.experiment.trials import TRIAL_TRAIN, validation_inputs
from sim.experiment.tuning import search_space
from sim.studies.benchmark.config import LEAN, BenchConfig, seed_count


def generation_seconds(configs: list, execution: Execution) -> float:
    """CPU seconds of making the data of ``configs`` that the cache does not hold yet: the first
    of them generated here (one process, so its CPU time is this process's; the cache then holds
    it for the run), counted once for each. A board's driver makes every evaluation seed's data
    beside the running jobs: on ``traffic``, whose highway-env scenes are slow to make, about
    100 CPU s a seed."""
    missing = [config for config in configs if not is_cached(config, execution)]
    if not missing:
        return 0.0
    started = time.process_time()
    prepare(missing[0], replace(execution, workers=1))  # the same data whatever the workers
    return (time.process_time() - started) * len(missing)


def tuning_runs(bench: BenchConfig, method: str) -> int:
    """The tuning runs of ``method``: none where it has nothing to tune or the settings are
    borrowed; the staged design's grids (``Design.grid_runs``); else Optuna's trials and the
    race's runs."""
    space = search_space(method)
    if not space or bench.borrowed:
        return 0
    if bench.design is not None:
        return bench.design.grid_runs(space)
    return bench.trials + min(bench.race, bench.trials) * bench.race_seeds


def estimate_bench(bench: BenchConfig, execution: Execution) -> dict[str, Any]:
    """What a benchmark will cost, by the run's own estimate (``sim.experiment.estimate``, in
    CPU seconds of one thread): one tuning trial (``trial``) and one evaluation job (``job``) of
    each method; the trials each method gets (a race's runs count as trials); the CPU seconds of
    all of them, of the tuning alone, of making the data the cache lacks (every evaluation seed's,
    the race's tuning seeds'), and the wall time with ``execution.jobs`` at a time (the tuning's
    rounds hold a trial of every method, so it is shared out evenly, as is the data's making; the
    evaluation's jobs go longest first). The decisive pair's extra seeds are not counted: how
    many it needs is known only after."""
    torch.set_num_threads(execution.threads)
    tuning = bench.tuning().base
    tuning = replace(tuning, settings=layered(tuning, {"train": TRIAL_TRAIN}), record=False)
    evaluation = replace(bench.base, settings=layered(bench.base, {"train": LEAN}), record=False)
    trial = (  # another benchmark's settings (--tuned-from): no trial runs
        {}
        if bench.borrowed
        else job_seconds(tuning, validation_inputs(prepare(tuning, execution)).tasks)
    )
    job = job_seconds(evaluation, prepare(evaluation, execution).inputs.tasks)
    others = range(1, bench.base.seeds)  # seed 0's data made above; the pair's extra not known
    races = range(1, bench.race_seeds + 1) if bench.race and not bench.borrowed else range(0)
    generation = generation_seconds(  # each curriculum timed on its own: unlike sizes
        [replace(evaluation, seed=evaluation.seed + s) for s in others], execution
    ) + generation_seconds(
        [replace(tuning, seed=race_seed(tuning.seed, k)) for k in races], execution
    )
    trials = {m: tuning_runs(bench, m) for m in bench.ranked}
    tuning_cpu = sum(trials[m] * trial.get(m, 0.0) for m in bench.ranked)
    seeds = {m: seed_count(bench, m) for m in bench.base.methods}
    evaluation_cpu = sum(seeds[m] * job[m] for m in bench.base.methods)
    jobs = [job[m] for m in bench.base.methods for _ in range(seeds[m])]
    return {
        "trial": trial,
        "job": job,
        "trials": trials,
        "seeds": seeds,
        "cpu_seconds": tuning_cpu + evaluation_cpu + generation,
        "tuning_cpu_seconds": tuning_cpu,
        "generation_cpu_seconds": generation,  # shares the cores with the jobs
        "wall_seconds": (tuning_cpu + generation) / execution.jobs
        + lanes_seconds(jobs, execution.jobs),
        "jobs": execution.jobs,
    }


def estimate_line(cost: dict[str, Any], jobs: int) -> str:
    """The estimate in one line, as a board prints it before it starts."""
    generation = cost.get("generation_cpu_seconds", 0.0)
    made = f", {generation:.0f} of them making data" if generation else ""
    return (
        f"{sum(cost['trials'].values())} tuning trials and {sum(cost['seeds'].values())} "
        f"evaluation jobs, {jobs} at a time: about {describe(cost['wall_seconds'])} "
        f"({cost['cpu_seconds']:.0f} CPU s{made}, timed on this machine)"
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
