"""How close is a run's own time estimate to what its jobs then take, method by method?

For each method: the estimate ``sim.run`` prints before it starts (``job_seconds``: a few timed
training steps of the first two tasks with the method's hooks, one evaluation and one set of
diagnostics, scaled by the curriculum), then the job itself, run in the same process (one torch
thread, the domains already in the cache), and its CPU seconds of training and evaluation
(``result.json``'s ``cpu_seconds``). Prints both and their ratio; the issue's target is every
ratio within 0.75 to 1.25.

    python benchmarks/estimate_accuracy.py [--scenario crowd_noise_0.1..0.3] [--epochs 2]
        [--methods finetune,ewc,...]
"""

from __future__ import annotations

import argparse
import json
import tempfile
from pathlib import Path

import torch

from c2inet.methods.base import discover
from sim.experiment import Execution, ExperimentConfig, run_experiment
from sim.experiment.estimate import job_seconds
from sim.experiment.jobs import prepare


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--scenario", default="crowd_noise_0.1..0.3")
    p.add_argument("--epochs", type=int, default=2)
    p.add_argument("--methods", default=",".join(sorted(discover())))
    args = p.parse_args()
    torch.set_num_threads(1)
    execution = Execution(cache=Path(".cache/domains"), workers=1)
    print(f"{'method':16s} {'estimate':>9s} {'measured':>9s} {'ratio':>6s}")
    with tempfile.TemporaryDirectory() as tmp:
        for name in args.methods.split(","):
            config = ExperimentConfig(
                args.scenario, methods=(name,), epochs=args.epochs, record=False
            )
            estimate = job_seconds(config, prepare(config, execution).inputs.tasks)[name]
            run_experiment(config, Path(tmp) / name, execution)
            (path,) = (Path(tmp) / name / "jobs").glob("*/seed_0/result.json")
            measured = json.loads(path.read_text())["cpu_seconds"]
            ratio = estimate / measured if measured else float("nan")
            print(f"{name:16s} {estimate:8.1f}s {measured:8.1f}s {ratio:6.2f}", flush=True)


if __name__ == "__main__":
    from viz.cli import run_script

    raise SystemExit(run_script(main))
