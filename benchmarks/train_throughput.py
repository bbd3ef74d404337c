"""Training throughput of every method on the same data, side by side in one run.

Trains each method on the same two tasks of a scenario and prints training scenes per second
(the task's scenes passed through a training step over the CPU time of training and the
method's hooks, evaluation excluded; CPU time, since one torch thread makes it the wall time of
an idle machine and keeps a busy one's other work out) and each method's cost relative to
fine-tuning; the targets (issue 25): C2INet-online and A-GEM at most 1.3x, DER++ 1.6x. Each
method's figure is the best of ``--repeats`` rounds, the methods interleaved within each round.

    python benchmarks/train_throughput.py [--scenario crowd_noise_0.1,0.2] [--epochs 10]
        [--repeats 3] [--threads 1] [--methods all]

A method may carry options and a backbone, to compare variants in one run: ``--methods
finetune,derpp,derpp:replay_loss=point,finetune@stgat-cell``.

Run it on 2-agent scenes too (``--scenario crowd_radius_0.1,0.2``), where fixed costs weigh more.
"""

from __future__ import annotations

import argparse
import sys
import time

import torch

from c2inet.errors import InputError
from c2inet.methods.base import Method, discover, get_method
from c2inet.model_config import ModelConfig
from c2inet.trainer import ContinualTrainer, Task, TrainConfig
from sim.domains import build_domain
from sim.experiment.config import parse_settings
from sim.scenario import parse_scenario


def build_method(spec: str) -> Method:
    """The method ``spec`` names: ``NAME`` or ``NAME:KEY=VALUE:...``, then ``@BACKBONE``."""
    spec, _, backbone = spec.partition("@")
    name, *options = spec.split(":")
    settings = parse_settings([f"{name}.{option}" for option in options]).get(name, {})
    model = ModelConfig(backbone=backbone) if backbone else ModelConfig()
    return get_method(name)(model, settings)


def training_rate(spec: str, tasks: list[Task], epochs: int) -> tuple[float, int]:
    """CPU seconds spent training (hooks included, evaluation excluded) and scenes trained on,
    for the method ``spec`` (:func:`build_method`)."""
    method = build_method(spec)
    trainer = ContinualTrainer(method, tasks, TrainConfig(epochs=epochs, val_every=0))
    seconds, scenes = 0.0, 0
    original = trainer._train_task

    def timed(ctx):
        nonlocal seconds, scenes
        # counted before training: after_task may grow what training_windows returns
        scenes += len(method.training_windows(ctx)) * epochs
        start = time.process_time()
        original(ctx)
        seconds += time.process_time() - start

    trainer._train_task = timed
    trainer.run()
    return seconds, scenes


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--scenario", default="crowd_noise_0.1,0.2")
    p.add_argument("--epochs", type=int, default=10)
    p.add_argument("--methods", default="all", help="comma-separated, or all (default)")
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--threads", type=int, default=1, help="torch intra-op threads (default 1)")
    args = p.parse_args()
    trained = sorted(n for n, cls in discover().items() if cls.trains and n != "finetune")
    names = ["finetune", *trained] if args.methods == "all" else args.methods.split(",")
    try:  # a bad method or option: one line, before the domains are made
        for name in names:
            build_method(name)
        specs = parse_scenario(args.scenario)
    except (InputError, KeyError, ValueError) as error:  # KeyError: get_method names the methods
        print(f"error: {error.args[0]}", file=sys.stderr)
        sys.exit(2)
    torch.set_num_threads(args.threads)
    tasks = []
    for spec in specs:
        d = build_domain(spec, 0)
        tasks.append(Task(d.name, d.windows("train"), None, d.windows("test")))
    print(
        f"torch threads: {torch.get_num_threads()}; tasks: {[t.name for t in tasks]}; "
        f"train scenes per task: {[len(t.train) for t in tasks]}; epochs: {args.epochs}; "
        f"best of {args.repeats} interleaved rounds"
    )
    best: dict[str, tuple[float, int]] = {}
    for _ in range(args.repeats):  # interleaved, so a slow spell of the machine hits every method
        for name in names:
            seconds, scenes = training_rate(name, tasks, args.epochs)
            if name not in best or seconds < best[name][0]:
                best[name] = (seconds, scenes)
    print(f"{'method':<24}{'CPU s':>10}{'scenes':>9}{'scenes/s':>10}{'vs finetune':>13}")
    base = None
    for name in names:
        seconds, scenes = best[name]
        rate = scenes / seconds
        base = base or rate
        print(f"{name:<24}{seconds:>10.1f}{scenes:>9}{rate:>10.0f}{base / rate:>12.2f}x")


if __name__ == "__main__":
    main()
