"""Does C2INet's queue shape training? Free bits of KL_C against the share of scenes it binds in.

Trains C2INet-online on a curriculum that no reported table uses (default: the radius preset's
tuning curriculum, scored on its validation splits) at each ``--free-bits`` value, with the KL of
C against the queue's mixture (Eq 17) and, beside each, against N(0, I) (``eq17=false``: the
queue then acts only through its anchors). Prints, mean ± std over seeds: the final average
validation ADE of the point prediction, the smallest share over tasks of the last epoch's scenes
whose KL_C had a gradient, KL_C and KL_Z (nats) and MI(X; C) of the last task's last epoch, and
how far switching Eq 17 off moves the ADE (paired over seeds).

    python benchmarks/c2inet_binding.py [--scenario crowd_radius_0.15..0.55:0.2]
        [--free-bits 0,1,2,4,8] [--seeds 3] [--epochs 20] [--jobs 2] [--set SCOPE.KEY=VALUE]
"""

from __future__ import annotations

import argparse
from concurrent.futures import ProcessPoolExecutor
from itertools import product

import numpy as np
import torch

from c2inet.methods.base import get_method
from c2inet.model_config import ModelConfig
from c2inet.significance import paired
from c2inet.trainer import ContinualTrainer, Task, TrainConfig
from sim.domains import build_domain
from sim.experiment.config import parse_settings
from sim.scenario import parse_scenario


def one_run(scenario: str, free_bits: float, eq17: bool, seed: int, epochs: int, given: dict):
    """One seed of C2INet-online at ``free_bits``: its figures on the validation splits."""
    torch.set_num_threads(1)
    tasks = []
    for spec in parse_scenario(scenario, overrides=given.get("data")):
        domain = build_domain(spec, seed)
        val = domain.windows("val")
        tasks.append(Task(domain.name, domain.windows("train"), val, val))
    model = ModelConfig(**{**given.get("model", {}), "free_bits_c": free_bits})
    method = get_method("c2inet-online")(model, {**given.get("c2inet-online", {}), "eq17": eq17})
    train = TrainConfig(
        **{
            **given.get("train", {}),
            "epochs": epochs,
            "val_every": 0,
            "diagnostics": False,
            "test_rules": False,
            "seed": seed,
        }
    )
    result = ContinualTrainer(method, tasks, train).run()
    last = {}
    for record in result.history:  # the last epoch of each task
        last[record["task"]] = record
    final = last[max(last)]
    return {
        "ade": float(np.mean(result.matrices["ade_k1"][-1])),
        "binding": min(r.get("kl_c_binding", float("nan")) for r in last.values()),
        "kl_c": final.get("kl_c", float("nan")),
        "kl_z": final.get("kl_z", float("nan")),
        "mi_c": final.get("mi_c", float("nan")),
    }


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--scenario", default="crowd_radius_0.15..0.55:0.2")
    p.add_argument("--free-bits", default="0,1,2,4,8")
    p.add_argument("--seeds", type=int, default=3)
    p.add_argument("--epochs", type=int, default=20)
    p.add_argument("--jobs", type=int, default=2)
    p.add_argument("--set", action="append", default=[], dest="settings")
    args = p.parse_args()
    given = parse_settings(args.settings)
    values = [float(v) for v in args.free_bits.split(",")]
    runs = list(product(values, (True, False), range(args.seeds)))
    with ProcessPoolExecutor(args.jobs) as pool:
        futures = [
            pool.submit(one_run, args.scenario, fb, eq17, seed, args.epochs, given)
            for fb, eq17, seed in runs
        ]
        results = {run: future.result() for run, future in zip(runs, futures, strict=True)}
    print(f"{args.scenario} (validation splits), {args.seeds} seeds, {args.epochs} epochs a task")
    print(
        f"{'free bits':>9} {'Eq 17':>6} {'val ADE':>15} {'binds (min task)':>17} "
        f"{'KL_C':>6} {'KL_Z':>6} {'MI':>5} {'Eq 17 off moves ADE [95 % CI]':>30}"
    )
    for fb, eq17 in product(values, (True, False)):
        rows = [results[(fb, eq17, s)] for s in range(args.seeds)]
        ade = [r["ade"] for r in rows]
        cells = {k: np.nanmean([r[k] for r in rows]) for k in ("binding", "kl_c", "kl_z", "mi_c")}
        moved = ""
        if not eq17:
            on = [results[(fb, True, s)]["ade"] for s in range(args.seeds)]
            test = paired(ade, on)
            low, high = test.interval or (float("nan"), float("nan"))
            moved = f"{test.difference:+.4f} [{low:+.4f}, {high:+.4f}]"
        print(
            f"{fb:>9g} {'on' if eq17 else 'off':>6} {np.mean(ade):>7.4f} ± {np.std(ade):.4f} "
            f"{cells['binding']:>17.2f} {cells['kl_c']:>6.2f} {cells['kl_z']:>6.3f} "
            f"{cells['mi_c']:>5.2f} {moved:>30}"
        )


if __name__ == "__main__":
    from viz.cli import run_script

    raise SystemExit(run_script(main))
