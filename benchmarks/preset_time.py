"""Where the fair benchmark's time goes, by the run's own estimate (``sim.experiment.estimate``).

For a preset at the default sizes, times every method's tuning trial (the tuning curriculum's
validation data, trained as a trial is: no diagnostics, validation curves or other test-time
rules) and evaluation job (the preset's curriculum) on this machine, one torch thread, and prints
per method and side by side the seconds of one of each, of all its trials and seeds, and its
share; then the total CPU seconds and the wall time they make with ``--jobs`` at a time. An
estimate, within 25 % of measured jobs for 16 or 17 of the 18 methods (``estimate_accuracy.py``).

    python benchmarks/preset_time.py [--preset radius] [--methods all] [--trials 6] [--seeds 5]
        [--jobs 2]
"""

from __future__ import annotations

import argparse
from dataclasses import replace
from pathlib import Path

import torch

from sim.cli import method_names
from sim.experiment import ExperimentConfig
from sim.experiment.bench import PRESETS, BenchConfig
from sim.experiment.config import Execution
from sim.experiment.estimate import describe, job_seconds, run_seconds
from sim.experiment.jobs import prepare
from sim.experiment.sweep import layered
from sim.experiment.tuning import TRIAL_TRAIN, search_space, validation_inputs


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--preset", default="radius", choices=sorted(PRESETS))
    p.add_argument("--methods", default="all")
    p.add_argument("--trials", type=int, default=6)
    p.add_argument("--seeds", type=int, default=5)
    p.add_argument("--jobs", type=int, default=2)
    args = p.parse_args()
    torch.set_num_threads(1)
    preset, methods = PRESETS[args.preset], method_names(args.methods)
    base = ExperimentConfig(preset.scenario, methods=methods, seeds=args.seeds, record=False)
    tuning = BenchConfig(base, preset.tune_scenario, args.trials).tuning().base
    tuning = replace(tuning, settings=layered(tuning, {"train": TRIAL_TRAIN}))
    execution = Execution(cache=Path(".cache/domains"))
    trial = job_seconds(tuning, validation_inputs(prepare(tuning, execution)).tasks)
    job = job_seconds(base, prepare(base, execution).inputs.tasks)
    trials = {m: args.trials if search_space(m) else 0 for m in methods}
    spent = {m: trials[m] * trial[m] + args.seeds * job[m] for m in methods}
    total = sum(spent.values())
    print(
        f"{preset.scenario}, tuned on {tuning.scenario}: {args.trials} trials, {args.seeds} seeds"
    )
    print(
        f"{'method':16s} {'trial s':>8s} {'job s':>7s} {'tuning s':>9s} {'eval s':>7s} "
        f"{'share':>6s}"
    )
    for m in sorted(methods, key=spent.get, reverse=True):
        cells = (
            f"{trial[m]:8.0f} {job[m]:7.0f} {trials[m] * trial[m]:9.0f} {args.seeds * job[m]:7.0f}"
        )
        print(f"{m:16s} {cells} {spent[m] / total:6.1%}")
    tuning_total = sum(trials[m] * trial[m] for m in methods)
    evaluation = run_seconds(base, job, args.jobs)
    wall = tuning_total / args.jobs + evaluation  # the tuning's rounds hold many methods each
    print(f"CPU seconds: {total:.0f} ({tuning_total / total:.0%} tuning)")
    print(f"wall with --jobs {args.jobs}: about {describe(wall)} (target: 60 min)")


if __name__ == "__main__":
    main()
