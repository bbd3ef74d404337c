"""Training throughput of every method on the same data, side by side in one run.

Trains each method on the same two tasks of each scenario (by default 10-agent crowds,
``crowd_noise_0.1,0.2``, and 2-agent ones, ``crowd_radius_0.1,0.2``) and prints training scenes
per second (the tasks' scenes passed through a training step over the CPU time of training and
the method's hooks, evaluation excluded; CPU time, since one torch thread makes it the wall time
of an idle machine and keeps a busy one's other work out), each method's cost relative to the
first, and the arithmetic it achieves: the matrix products' FLOPs of a scene's training (counted
by torch's FlopCounterMode in a pass of its own) times scenes/s, against the rate of one large
single-thread matrix product on this machine (issue 48's goal: 30 %). Each method's figure is
the best of ``--repeats`` rounds, the methods interleaved within each round.

    python benchmarks/train_throughput.py [--scenario crowd_noise_0.1,0.2 ...] [--epochs 10]
        [--repeats 3] [--threads 1] [--methods all]

A method may carry options and a backbone, to compare variants in one run: ``--methods
finetune,finetune@stgat-cell,derpp,derpp:replay_loss=point``.
"""

from __future__ import annotations

import argparse
import sys
import time

import torch
from torch.utils.flop_counter import FlopCounterMode

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


def training_rate(
    spec: str, tasks: list[Task], epochs: int, count_flops: bool = False
) -> tuple[float, int, float]:
    """CPU seconds spent training (hooks included, evaluation excluded), scenes trained on and,
    with ``count_flops``, the matrix products' FLOPs of that training (slower: timed apart),
    for the method ``spec`` (:func:`build_method`)."""
    method = build_method(spec)
    trainer = ContinualTrainer(method, tasks, TrainConfig(epochs=epochs, val_every=0))
    seconds, scenes, flops = 0.0, 0, 0.0
    original = trainer._train_task

    def timed(ctx):
        nonlocal seconds, scenes, flops
        # counted before training: after_task may grow what training_windows returns
        scenes += len(method.training_windows(ctx)) * epochs
        start = time.process_time()
        if count_flops:
            with FlopCounterMode(display=False) as counter:
                original(ctx)
            flops += counter.get_total_flops()
        else:
            original(ctx)
        seconds += time.process_time() - start

    trainer._train_task = timed
    trainer.run()
    return seconds, scenes, flops


def matmul_rate(size: int = 2048, repeats: int = 5) -> float:
    """GFLOP/s of one large float32 matrix product on this machine's torch threads (best of)."""
    a, b = torch.randn(size, size), torch.randn(size, size)
    best = float("inf")
    for _ in range(repeats):
        start = time.process_time()
        a @ b
        best = min(best, time.process_time() - start)
    return 2 * size**3 / best / 1e9


def scenario_table(names: list[str], tasks: list[Task], args, peak: float) -> None:
    """The methods' rates on one scenario's tasks, printed as one table."""
    flops = {name: training_rate(name, tasks, 1, count_flops=True) for name in names}
    best: dict[str, tuple[float, int]] = {}
    for _ in range(args.repeats):  # interleaved, so a slow spell of the machine hits every method
        for name in names:
            seconds, scenes, _ = training_rate(name, tasks, args.epochs)
            if name not in best or seconds < best[name][0]:
                best[name] = (seconds, scenes)
    agents = sum(len(t.train.positions) for t in tasks) / sum(len(t.train) for t in tasks)
    print(
        f"\n{' + '.join(t.name for t in tasks)}: {agents:.1f} agents a scene, train scenes "
        f"{[len(t.train) for t in tasks]}, {args.epochs} epochs, best of {args.repeats} rounds"
    )
    print(
        f"{'method':<28}{'CPU s':>8}{'scenes/s':>10}{'vs first':>10}"
        f"{'MFLOP/scene':>13}{'GFLOP/s':>9}{'of matmul':>11}"
    )
    base = None
    for name in names:
        seconds, scenes = best[name]
        rate = scenes / seconds
        base = base or rate
        _, counted_scenes, counted = flops[name]
        per_scene = counted / counted_scenes
        achieved = per_scene * rate / 1e9
        print(
            f"{name:<28}{seconds:>8.1f}{rate:>10.0f}{base / rate:>9.2f}x"
            f"{per_scene / 1e6:>13.1f}{achieved:>9.1f}{achieved / peak:>10.0%}"
        )


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--scenario", action="append", help="repeatable (default: 10- and 2-agent)")
    p.add_argument("--epochs", type=int, default=10)
    p.add_argument("--methods", default="all", help="comma-separated, or all (default)")
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--threads", type=int, default=1, help="torch intra-op threads (default 1)")
    args = p.parse_args()
    trained = sorted(n for n, cls in discover().items() if cls.trains and n != "finetune")
    names = ["finetune", *trained] if args.methods == "all" else args.methods.split(",")
    scenarios = args.scenario or ["crowd_noise_0.1,0.2", "crowd_radius_0.1,0.2"]
    try:  # a bad method or option: one line, before the domains are made
        for name in names:
            build_method(name)
        curricula = [parse_scenario(scenario) for scenario in scenarios]
    except (InputError, KeyError, ValueError) as error:  # KeyError: get_method names the methods
        print(f"error: {error.args[0]}", file=sys.stderr)
        sys.exit(2)
    torch.set_num_threads(args.threads)
    peak = matmul_rate()
    print(
        f"torch threads: {torch.get_num_threads()}; one 2048^3 float32 matmul: {peak:.0f} GFLOP/s"
    )
    for specs in curricula:
        tasks = []
        for spec in specs:
            d = build_domain(spec, 0)
            tasks.append(Task(d.name, d.windows("train"), None, d.windows("test")))
        scenario_table(names, tasks, args, peak)


if __name__ == "__main__":
    from viz.cli import run_script

    raise SystemExit(run_script(main))
