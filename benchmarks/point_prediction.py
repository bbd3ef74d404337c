"""Which point prediction should K = 1 score? The two candidates side by side, with one draw.

Trains fine-tuning, C2INet-online, GCRL and PECNet through ``crowd_radius_0.1..0.3`` (default
sizes, ``--epochs`` each, one torch thread) and scores, on every task's test split, the ADE of:
the mean of 16 sampled futures (the testbed's ``ade_k1``), the model's latents at their means
(``Predictor.point``: zero noise, or C2INet's posterior means of C then Z, PECNet's z = 0), and
one random draw (``ade_draw``). Prints one row per method.

    python benchmarks/point_prediction.py [--epochs 4] [--seeds 2]
"""

from __future__ import annotations

import argparse

import numpy as np
import torch

from c2inet.batch import batches
from c2inet.evaluation import sample_predictions
from c2inet.methods.base import get_method
from c2inet.metrics import displacement_errors
from c2inet.model import to_positions
from c2inet.model_config import ModelConfig
from c2inet.trainer import ContinualTrainer, TrainConfig
from sim import learner_tasks

METHODS = ("finetune", "c2inet-online", "gcrl", "pecnet")


@torch.no_grad()
def latents_at_means(model, windows) -> np.ndarray:
    model.eval()
    parts = [to_positions(b, model.point(b)[:, None])[0].numpy() for b in batches(windows, 256)]
    return np.concatenate(parts, axis=1)  # (T, N, 2)


def scores(model, windows, seed: int) -> tuple[float, float, float]:
    truth = windows.positions[:, windows.obs_len :].transpose(1, 0, 2)
    draws = sample_predictions(model, windows, 16, seed)
    mean = displacement_errors(draws.mean(0, keepdims=True), truth)[0].mean()
    at_means = displacement_errors(latents_at_means(model, windows)[None], truth)[0].mean()
    one = displacement_errors(draws[:1], truth)[0].mean()
    return float(mean), float(at_means), float(one)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--epochs", type=int, default=4)
    p.add_argument("--seeds", type=int, default=2)
    args = p.parse_args()
    torch.set_num_threads(1)
    tasks = learner_tasks("crowd_radius_0.1..0.3")
    print(f"{'method':16s} {'mean of 16':>11s} {'latents at means':>17s} {'one draw':>9s}")
    for name in METHODS:
        rows = []
        for seed in range(args.seeds):
            method = get_method(name)(ModelConfig())
            trainer = ContinualTrainer(
                method, tasks, TrainConfig(epochs=args.epochs, seed=seed, diagnostics=False)
            )
            trainer.run()
            rows.append([scores(trainer.model, t.test, seed) for t in tasks])
        mean, at_means, one = np.mean(rows, axis=(0, 1))
        print(f"{name:16s} {mean:11.3f} {at_means:17.3f} {one:9.3f}")
    print("ADE in metres after the last task, mean over the tasks and seeds")


if __name__ == "__main__":
    from viz.cli import run_script

    raise SystemExit(run_script(main))
