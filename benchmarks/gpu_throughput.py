"""Training throughput on the GPU against the CPU, side by side in one run.

Trains each method on the same two crowd tasks on every device asked for (the CPU with one
torch thread, and CUDA where there is one), at each batch size asked for, and prints training
scenes per second by wall time (the GPU's queue drained before the clock stops: a GPU's work is
asynchronous, so CPU time says nothing of it), each row's speed against the CPU's at the same
batch size. A step reads nothing back to the host (``tests/c2inet/test_training_recipe.py``
counts it), so the GPU's queue is never drained mid-epoch. Devices and batch sizes are
interleaved within each round; each figure is the best of ``--repeats`` rounds.

    python benchmarks/gpu_throughput.py [--methods finetune,c2inet-online,derpp]
        [--batches 16,64,256] [--devices cpu,cuda] [--epochs 3] [--repeats 2]

Without a CUDA device the CUDA rows say so and the CPU rows still print.
"""

from __future__ import annotations

import argparse
import time

import torch

from c2inet.errors import InputError
from c2inet.methods.base import get_method
from c2inet.model_config import ModelConfig
from c2inet.trainer import ContinualTrainer, Task, TrainConfig
from sim.domains import build_domain
from sim.scenario import parse_scenario

SCENARIO = "crowd_noise_0.1,0.2"


def drained(device: str) -> None:
    """Wait for the device's queued work (a no-op on the CPU)."""
    if device.startswith("cuda"):
        torch.cuda.synchronize()


def training_rate(method: str, tasks: list[Task], device: str, batch: int, epochs: int) -> float:
    """Training scenes per wall-clock second of ``method`` on ``device`` (evaluation excluded)."""
    config = TrainConfig(epochs=epochs, batch_scenes=batch, val_every=0, device=device)
    trainer = ContinualTrainer(get_method(method)(ModelConfig()), tasks, config)
    seconds, scenes = 0.0, 0
    original = trainer._train_task

    def timed(ctx):
        nonlocal seconds, scenes
        scenes += len(trainer.method.training_windows(ctx)) * epochs
        drained(device)
        start = time.perf_counter()
        original(ctx)
        drained(device)
        seconds += time.perf_counter() - start

    trainer._train_task = timed
    trainer.run()
    return scenes / seconds


def available(device: str) -> bool:
    return device == "cpu" or (device.startswith("cuda") and torch.cuda.is_available())


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--methods", default="finetune,c2inet-online,derpp")
    p.add_argument("--batches", default="16,64,256", help="scenes a step, comma-separated")
    p.add_argument("--devices", default="cpu,cuda")
    p.add_argument("--epochs", type=int, default=3)
    p.add_argument("--repeats", type=int, default=2)
    args = p.parse_args()
    methods, devices = args.methods.split(","), args.devices.split(",")
    try:
        batches = [int(b) for b in args.batches.split(",")]
    except ValueError:
        raise InputError(f"--batches {args.batches!r}: whole numbers, comma-separated") from None
    for method in methods:
        get_method(method)  # an unknown name: one line, before the domains are made
    torch.set_num_threads(1)
    tasks = []
    for spec in parse_scenario(SCENARIO):
        domain = build_domain(spec, 0)
        tasks.append(Task(domain.name, domain.windows("train"), None, domain.windows("test")))
    runnable = [d for d in devices if available(d)]
    best: dict[tuple[str, str, int], float] = {}
    for _ in range(args.repeats):  # interleaved, so a slow spell of the machine hits every row
        for method in methods:
            for batch in batches:
                for device in runnable:
                    rate = training_rate(method, tasks, device, batch, args.epochs)
                    key = (method, device, batch)
                    best[key] = max(best.get(key, 0.0), rate)
    gpu = torch.cuda.get_device_name() if torch.cuda.is_available() else "none"
    print(f"{SCENARIO}, {args.epochs} epochs a task, best of {args.repeats}; CUDA device: {gpu}")
    print(f"{'method':<16}{'device':<8}{'batch':>6}{'scenes/s':>10}{'vs CPU':>8}")
    for method in methods:
        for batch in batches:
            for device in devices:
                if device not in runnable:
                    print(f"{method:<16}{device:<8}{batch:>6}{'not available here':>28}")
                    continue
                rate, cpu = best[(method, device, batch)], best.get((method, "cpu", batch))
                versus = f"{rate / cpu:>7.2f}x" if cpu else f"{'-':>8}"
                print(f"{method:<16}{device:<8}{batch:>6}{rate:>10.0f}{versus}")


if __name__ == "__main__":
    from viz.cli import run_script

    raise SystemExit(run_script(main))
