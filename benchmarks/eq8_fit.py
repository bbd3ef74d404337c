"""Eq 8's component fit by autograd against its gradient in closed form, side by side.

Two rows per size: one fit alone (200 Adam steps of 64 samples, the defaults; a target of
``target`` components, a queue of ``queue``), and C2INet-online's training (hooks included,
evaluation excluded) on two tasks with each ``QueueConfig.fit``. CPU seconds, best of
``--repeats`` interleaved rounds, one torch thread.

    python benchmarks/eq8_fit.py [--scenario crowd_radius_0.1,0.2] [--epochs 4] [--repeats 3]
"""

from __future__ import annotations

import argparse
import time

import torch

from c2inet.gaussians import GaussianMixture
from c2inet.methods.base import get_method
from c2inet.model_config import ModelConfig
from c2inet.prior import PriorQueue, QueueConfig
from c2inet.trainer import ContinualTrainer, Task, TrainConfig
from sim.domains import build_domain
from sim.scenario import parse_scenario

FITS = ("autograd", "closed")


def mixture(k: int, generator: torch.Generator) -> GaussianMixture:
    means = torch.randn(k, 8, generator=generator)
    logvars = 0.3 * torch.randn(k, 8, generator=generator) - 1
    return GaussianMixture(means, logvars, torch.ones(k) / k)


def fit_seconds(kind: str, target: int, queue_size: int) -> float:
    g = torch.Generator().manual_seed(0)
    queue = PriorQueue(8, QueueConfig(fit=kind))
    for k in range(queue_size):
        queue.add(torch.randn(8, generator=g), torch.zeros(8) - 1, 1 / (k + 2), owner=k)
    goal = mixture(target, g)
    start = time.process_time()
    queue.fit_component(goal, g)
    return time.process_time() - start


def training_seconds(kind: str, tasks: list[Task], epochs: int) -> float:
    method = get_method("c2inet-online")(ModelConfig(), {"fit": kind})
    config = TrainConfig(epochs=epochs, val_every=0, diagnostics=False)
    trainer = ContinualTrainer(method, tasks, config)
    spent = 0.0
    original = trainer._train_task

    def timed(ctx):
        nonlocal spent
        start = time.process_time()
        original(ctx)
        spent += time.process_time() - start

    trainer._train_task = timed
    trainer.run()
    return spent


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--scenario", default="crowd_radius_0.1,0.2")
    p.add_argument("--epochs", type=int, default=4)
    p.add_argument("--repeats", type=int, default=3)
    args = p.parse_args()
    torch.set_num_threads(1)
    tasks = []
    for spec in parse_scenario(args.scenario):
        d = build_domain(spec, 0)
        tasks.append(Task(d.name, d.windows("train"), None, d.windows("test")))
    fit_seconds("autograd", 4, 2)  # torch's first optimiser imports torch._dynamo: not timed
    rows = {f"one fit, target {t}, queue {q}": (t, q) for t, q in ((256, 10), (301, 45))}
    best: dict[tuple[str, str], float] = {}
    for _ in range(args.repeats):  # interleaved: a slow spell of the machine hits both
        for kind in FITS:
            for row, (target, queue) in rows.items():
                seconds = fit_seconds(kind, target, queue)
                best[row, kind] = min(best.get((row, kind), seconds), seconds)
            seconds = training_seconds(kind, tasks, args.epochs)
            row = f"C2INet-online training, {args.epochs} epochs x {len(tasks)} tasks"
            best[row, kind] = min(best.get((row, kind), seconds), seconds)
    print(
        f"CPU seconds, best of {args.repeats}; {args.scenario}, train scenes "
        f"{[len(t.train) for t in tasks]}"
    )
    print(f"{'':48s}{'autograd':>10s}{'closed':>10s}{'ratio':>8s}")
    for row in dict.fromkeys(r for r, _ in best):
        a, c = best[row, "autograd"], best[row, "closed"]
        print(f"{row:48s}{a:10.3f}{c:10.3f}{a / c:7.2f}x")


if __name__ == "__main__":
    from viz.cli import run_script

    raise SystemExit(run_script(main))
