"""What pruning saves in a benchmark's tuning, and whether it changes what tuning chooses.

Tunes each method on a preset's tuning curriculum (default sizes, one torch thread a job) twice,
the same trials drawn from the same seeds: with pruning (trials worse than the median of the
finished ones stop after a task) and without. Prints, per method and side by side, the trials'
CPU seconds, the trials pruned, the settings chosen and their validation objective, and whether
a pruned trial would have been the best had it run to the end (the unpruned tuning says).

    python benchmarks/tuning_pruning.py [--preset radius] [--trials 6] [--warmup 1] [--jobs 2]
        [--methods finetune,ewc,agem,derpp,c2inet-online] [--quick] [--out DIR]

A folder already tuned is read back, so arms with other warm-ups reuse the full tuning.

Every method must have something to tune (not ``cv``).
"""

from __future__ import annotations

import argparse
import time
from dataclasses import replace
from pathlib import Path

from sim.experiment import ExperimentConfig
from sim.experiment.config import Execution
from sim.experiment.trials import trial_results
from sim.experiment.tuning import run_tuning
from sim.studies.benchmark.config import BenchConfig
from sim.studies.benchmark.presets import PRESETS


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--preset", default="radius", choices=sorted(PRESETS))
    p.add_argument("--methods", default="finetune,ewc,agem,derpp,c2inet-online")
    p.add_argument("--trials", type=int, default=6)
    p.add_argument("--jobs", type=int, default=2)
    p.add_argument("--warmup", type=int, default=1, help="tasks after which none is pruned (1)")
    p.add_argument("--quick", action="store_true", help="tiny sizes: a smoke test")
    p.add_argument("--out", type=Path, default=Path("runs/tuning_pruning"))
    args = p.parse_args()
    preset = PRESETS[args.preset]
    methods = tuple(args.methods.split(","))
    base = ExperimentConfig(preset.scenario, methods=methods, quick=args.quick, record=False)
    tuning = BenchConfig(base, tune_scenario=preset.tune_scenario, trials=args.trials).tuning()
    execution = Execution(jobs=args.jobs, cache=Path(".cache/domains"))
    folders = {True: args.out / f"pruned_warmup{args.warmup}", False: args.out / "full"}
    chosen, wall = {}, {}
    for prune, folder in folders.items():  # a folder already tuned is read back
        started = time.perf_counter()
        arm = replace(tuning, prune=prune, warmup_tasks=args.warmup)
        chosen[prune] = run_tuning(arm, folder, execution)
        wall[prune] = time.perf_counter() - started
    print(
        f"tuning on {tuning.base.scenario}, {args.trials} trials a method, --jobs {args.jobs}, "
        f"none pruned after the first {args.warmup} task(s)"
    )
    print(
        f"{'method':15s} {'CPU s pruned':>12s} {'full':>7s} {'ratio':>6s} {'pruned':>6s} "
        f"{'objective pruned':>16s} {'full':>7s} {'same choice':>11s} {'best pruned':>11s}"
    )
    total = {True: 0.0, False: 0.0}
    for method in methods:
        cpu = {
            prune: sum(r["cpu_seconds"] for r in trial_results(folder, method))
            for prune, folder in folders.items()
        }
        total = {prune: total[prune] + cpu[prune] for prune in total}
        pruned, full = chosen[True][method], chosen[False][method]
        count = sum(t["pruned"] for t in pruned["trials"])
        # a pruned trial that, run to the end by the full tuning, was its choice
        lost = any(
            a["pruned"] and a["params"] == b["params"] and b["objective"] == full["objective"]
            for a, b in zip(pruned["trials"], full["trials"], strict=True)
        )
        print(
            f"{method:15s} {cpu[True]:12.0f} {cpu[False]:7.0f} {cpu[False] / cpu[True]:5.2f}x "
            f"{count:6d} {pruned['objective']:16.4f} {full['objective']:7.4f} "
            f"{str(pruned['settings'] == full['settings']):>11s} {str(lost):>11s}"
        )
    ratio = total[False] / total[True]
    print(f"{'all':15s} {total[True]:12.0f} {total[False]:7.0f} {ratio:5.2f}x")
    print(f"wall seconds: {wall[True]:.0f} pruned, {wall[False]:.0f} full (0 where read back)")
    for method in methods:
        print(f"{method} chose: {chosen[True][method]['settings']} pruned")
        print(f"{' ' * len(method)}        {chosen[False][method]['settings']} full")


if __name__ == "__main__":
    from viz.cli import run_script

    raise SystemExit(run_script(main))
