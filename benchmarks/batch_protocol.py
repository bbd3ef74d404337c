"""The benchmark protocol's batch, before and after: the same methods and seeds at batch 16 and
at batch 64, each at its default learning rate and at a learning rate of its own per batch.

The fair benchmark trains at batch 64 (``sim/studies/benchmark.py``); this checks that the move
leaves the ranking and the gaps within their spread. Prints, per method and side by side, the
final point-prediction ADE (mean ± std over seeds), its rank, its gap to fine-tuning with the
paired interval, and the CPU seconds of a job.

    python benchmarks/batch_protocol.py [--scenario crowd_radius_0.1..0.6] [--seeds 5]
        [--methods finetune,c2inet-online,derpp,ewc] [--batches 16,64] [--jobs 2]
        [--set SCOPE.KEY=VALUE ...]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from c2inet.significance import paired
from sim.experiment import Execution, ExperimentConfig, run_experiment
from sim.experiment.config import parse_settings
from sim.experiment.trials import TRIAL_TRAIN


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--scenario", default="crowd_radius_0.1..0.6")
    p.add_argument("--methods", default="finetune,c2inet-online,derpp,ewc")
    p.add_argument("--seeds", type=int, default=5)
    p.add_argument("--batches", default="16,64")
    p.add_argument("--jobs", type=int, default=2)
    p.add_argument("--out", type=Path, default=Path("runs/batch_protocol"))
    p.add_argument("--set", action="append", default=[], dest="settings")
    args = p.parse_args()
    methods = tuple(args.methods.split(","))
    given = parse_settings(args.settings)
    results = {}
    for batch in (int(b) for b in args.batches.split(",")):
        train = {**TRIAL_TRAIN, **given.get("train", {}), "batch_scenes": batch}
        config = ExperimentConfig(
            args.scenario,
            methods=methods,
            seeds=args.seeds,
            settings={**given, "train": train},
            record=False,
        )
        out = args.out / f"batch_{batch}"
        resume = (out / "config.json").is_file()
        metrics = run_experiment(
            config, out=out, execution=Execution(jobs=args.jobs), resume=resume
        )
        results[batch] = metrics["methods"]
    print(f"{args.scenario}, {args.seeds} seeds; final point-prediction ADE (m), mean ± std")
    header = f"{'method':16s}" + "".join(
        f" | {'b' + str(b):>6s} ADE       rank  vs finetune [95 % CI]" for b in results
    )
    print(header)
    for method in methods:
        cells = []
        for summaries in results.values():
            mine = summaries[method]["final_ade_k1_per_seed"]
            order = sorted(summaries, key=lambda m: np.mean(summaries[m]["final_ade_k1_per_seed"]))
            test = paired(mine, summaries["finetune"]["final_ade_k1_per_seed"])
            low, high = test.interval or (0.0, 0.0)
            cells.append(
                f" | {np.mean(mine):.3f} ± {np.std(mine):.3f} {order.index(method) + 1:4d}"
                f"  {test.difference:+.3f} [{low:+.3f}, {high:+.3f}]"
            )
        print(f"{method:16s}" + "".join(cells))


if __name__ == "__main__":
    from viz.cli import run_script

    raise SystemExit(run_script(main))
