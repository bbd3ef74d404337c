"""What a tuning trial saves by skipping what its objective never reads.

Trains each method through ``crowd_radius_0.1..0.3`` (default sizes, ``--epochs`` a task, one
torch thread) twice, interleaved: as an evaluation run does (diagnostics, per-epoch validation
curves, every test-time rule for C) and as a tuning trial does (``TRIAL_TRAIN`` of
``sim/experiment/tuning.py``: none of them), and prints the CPU seconds of each, their ratio,
and that the trial's objective (final point-prediction ADE) is the same number.

    python benchmarks/trial_cost.py [--epochs 20] [--rounds 2] [--methods c2inet-online,finetune]
"""

from __future__ import annotations

import argparse
import time
from dataclasses import replace

import numpy as np
import torch

from c2inet.methods.base import get_method
from c2inet.model_config import ModelConfig
from c2inet.trainer import ContinualTrainer, TrainConfig
from sim import learner_tasks
from sim.experiment.trials import TRIAL_TRAIN


def cost(name: str, tasks, config: TrainConfig) -> tuple[float, float]:
    """(CPU seconds, final average point-prediction ADE) of one run."""
    started = time.process_time()
    result = ContinualTrainer(get_method(name)(ModelConfig()), tasks, config).run()
    seconds = time.process_time() - started
    return seconds, float(np.mean(result.matrices["ade_k1"][-1]))


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--epochs", type=int, default=20)
    p.add_argument("--rounds", type=int, default=2)
    p.add_argument("--methods", default="c2inet-online,finetune")
    args = p.parse_args()
    torch.set_num_threads(1)
    tasks = learner_tasks("crowd_radius_0.1..0.3")
    full = TrainConfig(epochs=args.epochs)
    trial = replace(full, **TRIAL_TRAIN)
    head = ("method", "evaluation run", "trial", "ratio", "same objective")
    print(f"{head[0]:16s} {head[1]:>15s} {head[2]:>8s} {head[3]:>6s} {head[4]:>15s}")
    for name in args.methods.split(","):
        runs = {"full": [], "trial": []}
        for _ in range(args.rounds):  # interleaved, best of the rounds
            for kind, config in (("full", full), ("trial", trial)):
                runs[kind].append(cost(name, tasks, config))
        best = {kind: min(s for s, _ in r) for kind, r in runs.items()}
        same = runs["full"][0][1] == runs["trial"][0][1]
        ratio = best["full"] / best["trial"]
        cells = f"{best['full']:14.1f}s {best['trial']:7.1f}s {ratio:6.2f} {str(same):>15s}"
        print(f"{name:16s} {cells}")
    print("CPU seconds (time.process_time), best of the rounds; ratio: evaluation run / trial")


if __name__ == "__main__":
    from viz.cli import run_script

    raise SystemExit(run_script(main))
