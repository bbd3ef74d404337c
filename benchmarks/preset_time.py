"""Where the fair benchmark's time goes, by the run's own estimate (``estimate_bench``).

For a preset at the protocol's sizes, times every method's tuning trial (the tuning
curriculum's validation data, trained as a trial is: no diagnostics, validation curves, other
test-time rules or unseen tasks) and evaluation job (the preset's curriculum, as lean) on this
machine in CPU seconds, one torch thread, and prints per method and side by side the seconds of
one of each, of all its trials and seeds, and its share; then the total CPU seconds and the wall
time they make with ``--jobs`` at a time. ``--epochs`` and ``--set`` size it otherwise.

    python benchmarks/preset_time.py [--preset radius] [--methods all] [--trials 10] [--seeds 8]
        [--jobs 2] [--epochs 20] [--set SCOPE.KEY=VALUE ...]
"""

from __future__ import annotations

import argparse
from pathlib import Path

from sim.cli import method_names
from sim.experiment import ExperimentConfig
from sim.experiment.config import Execution, parse_settings
from sim.experiment.estimate import describe
from sim.studies.benchmark import PRESETS, SEEDS, TRIALS
from sim.studies.benchmark.config import BenchConfig
from sim.studies.benchmark.estimate import estimate_bench


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--preset", default="radius", choices=sorted(PRESETS))
    p.add_argument("--methods", default="all")
    p.add_argument("--trials", type=int, default=TRIALS)
    p.add_argument("--seeds", type=int, default=SEEDS)
    p.add_argument("--jobs", type=int, default=2)
    p.add_argument("--epochs", type=int)
    p.add_argument("--set", action="append", default=[], dest="settings")
    args = p.parse_args()
    preset, methods = PRESETS[args.preset], method_names(args.methods)
    base = ExperimentConfig(
        preset.scenario,
        methods=methods,
        seeds=args.seeds,
        epochs=args.epochs,
        settings=parse_settings(args.settings),
        record=False,
    )
    bench = BenchConfig(
        base, name=args.preset, tune_scenario=preset.tune_scenario, trials=args.trials
    )
    cost = estimate_bench(bench, Execution(jobs=args.jobs, cache=Path(".cache/domains")))
    trial, job, trials, seeds = cost["trial"], cost["job"], cost["trials"], cost["seeds"]
    spent = {m: trials.get(m, 0) * trial.get(m, 0) + seeds[m] * job[m] for m in methods}
    tuned_on = bench.tuning().base.scenario
    print(f"{preset.scenario}, tuned on {tuned_on}: {args.trials} trials, {args.seeds} seeds")
    print(
        f"{'method':16s} {'trial s':>8s} {'job s':>7s} {'tuning s':>9s} {'eval s':>7s} "
        f"{'share':>6s}"
    )
    for m in sorted(methods, key=spent.get, reverse=True):
        tuning = trials.get(m, 0) * trial.get(m, 0)
        cells = f"{trial.get(m, 0):8.0f} {job[m]:7.0f} {tuning:9.0f} {seeds[m] * job[m]:7.0f}"
        print(f"{m:16s} {cells} {spent[m] / cost['cpu_seconds']:6.1%}")
    share = cost["tuning_cpu_seconds"] / cost["cpu_seconds"]
    print(f"CPU seconds: {cost['cpu_seconds']:.0f} ({share:.0%} tuning)")
    print(f"wall with --jobs {args.jobs}: about {describe(cost['wall_seconds'])} (target: 60 min)")


if __name__ == "__main__":
    from viz.cli import run_script

    raise SystemExit(run_script(main))
