"""Where the fair benchmark's time goes, by the run's own estimate (``estimate_bench``).

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
from pathlib import Path

from sim.cli import method_names
from sim.experiment import ExperimentConfig
from sim.experiment.bench import PRESETS, BenchConfig, estimate_bench
from sim.experiment.config import Execution
from sim.experiment.estimate import describe


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--preset", default="radius", choices=sorted(PRESETS))
    p.add_argument("--methods", default="all")
    p.add_argument("--trials", type=int, default=6)
    p.add_argument("--seeds", type=int, default=5)
    p.add_argument("--jobs", type=int, default=2)
    args = p.parse_args()
    preset, methods = PRESETS[args.preset], method_names(args.methods)
    base = ExperimentConfig(preset.scenario, methods=methods, seeds=args.seeds, record=False)
    bench = BenchConfig(base, preset.tune_scenario, args.trials)
    cost = estimate_bench(bench, Execution(jobs=args.jobs, cache=Path(".cache/domains")))
    trial, job, trials = cost["trial"], cost["job"], cost["trials"]
    spent = {m: trials[m] * trial[m] + args.seeds * job[m] for m in methods}
    tuned_on = bench.tuning().base.scenario
    print(f"{preset.scenario}, tuned on {tuned_on}: {args.trials} trials, {args.seeds} seeds")
    print(
        f"{'method':16s} {'trial s':>8s} {'job s':>7s} {'tuning s':>9s} {'eval s':>7s} "
        f"{'share':>6s}"
    )
    for m in sorted(methods, key=spent.get, reverse=True):
        cells = (
            f"{trial[m]:8.0f} {job[m]:7.0f} {trials[m] * trial[m]:9.0f} {args.seeds * job[m]:7.0f}"
        )
        print(f"{m:16s} {cells} {spent[m] / cost['cpu_seconds']:6.1%}")
    share = cost["tuning_cpu_seconds"] / cost["cpu_seconds"]
    print(f"CPU seconds: {cost['cpu_seconds']:.0f} ({share:.0%} tuning)")
    print(f"wall with --jobs {args.jobs}: about {describe(cost['wall_seconds'])} (target: 60 min)")


if __name__ == "__main__":
    main()
