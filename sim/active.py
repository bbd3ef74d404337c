"""``python -m sim.active``: an active curriculum simulates where the model fails.

``--scenario crowd_noise_0.1..0.6:0.05`` is a dense grid of one family's knob. With a budget of
``--rounds`` rounds of ``--scenes`` new training scenes each, every round a strategy picks the
knob value to simulate next, and the method learns those scenes (a task each round):

- ``error``: where the current model errs most on the grid's validation sets;
- ``relative``: where it errs most relative to constant velocity there (the model's error over
  the value's own difficulty: noise no model can predict raises both);
- ``spread``: where its samples disagree most there (no labels needed);
- ``fixed``: the grid in order, spread evenly over the rounds (the usual curriculum);
- ``random``: uniformly at random (``--random-orders`` orders, averaged).

Every strategy starts at the grid's first value, and the scenes of a value in a round are the
same whichever strategy asks for them. After each round the model is tested on the grid's
held-out test sets: mean and worst ADE against scenes simulated. It writes ``active.json``,
``active.md`` and ``active.png`` to ``--out``.
"""

from __future__ import annotations

import sys
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
import torch
from tqdm import tqdm

from c2inet.data import Windows
from c2inet.errors import InputError
from c2inet.files import write_atomic
from c2inet.options import check_range
from c2inet.stream import StreamLearner
from c2inet.trainer import Task, evaluate
from sim.cli import parse, parser
from sim.curriculum import knob_grid, make_tasks, scene_windows
from sim.domains import domain_seed
from sim.experiment import ExperimentConfig
from sim.generators import child_seed
from sim.outputs import write_report
from sim.run import add_learning_options, learning_config
from sim.scenario import DomainSpec
from viz.cli import bounded_int, guarded

STRATEGIES = ("error", "relative", "spread", "fixed", "random")


@dataclass(frozen=True)
class ActiveOptions:
    """The budget (rounds of new scenes) and the strategies compared."""

    rounds: int = 8
    scenes: int = 40
    strategies: tuple[str, ...] = STRATEGIES
    random_orders: int = 3

    def __post_init__(self):
        check_range("rounds", self.rounds, 1, 1000)
        check_range("scenes", self.scenes, 1, 100_000)
        check_range("random_orders", self.random_orders, 1, 100)
        unknown = sorted(set(self.strategies) - set(STRATEGIES))
        if unknown or not self.strategies:
            raise InputError(
                f"strategies: {unknown[0] if unknown else 'none given'!r} is not one of "
                f"{', '.join(STRATEGIES)}"
            )


def grid_specs(config: ExperimentConfig) -> list[DomainSpec]:
    """The grid: one numeric family that can simulate single scenes, two values or more."""
    where = f"scenario {config.scenario!r} (an active curriculum's grid)"
    return knob_grid(config.specs(), where, "crowd_noise_0.1..0.6:0.05", single_scenes=True)


class SceneSource:
    """New training scenes at a grid value: those of (round, value) are the same for every
    strategy, and never among the grid's validation or test scenes (their own seeds)."""

    def __init__(self, specs: list[DomainSpec], scenes: int, seed: int):
        self.specs, self.scenes = specs, scenes
        self.seeds = [
            domain_seed(seed, replace(spec, label=f"{spec.label}-active")) for spec in specs
        ]
        self.made: dict[tuple[int, int], Windows] = {}

    def draw(self, round_: int, index: int) -> Windows:
        if (round_, index) not in self.made:
            spec = self.specs[index]
            seeds = [child_seed(self.seeds[index], round_, k) for k in range(self.scenes)]
            self.made[round_, index] = scene_windows(spec.family, [spec.value] * self.scenes, seeds)
        return self.made[round_, index]


def run_strategy(
    strategy: str,
    order_seed: int,
    config: ExperimentConfig,
    method: str,
    tasks: list[Task],
    source: SceneSource,
    options: ActiveOptions,
    seed_index: int,
    baseline: list[float],
) -> dict[str, list]:
    """One strategy's rounds: the values it chose and the held-out errors after each.
    ``baseline``: constant velocity's validation ADE at each grid value."""
    train = replace(config.train_config(seed_index), diagnostics=False, val_every=0)
    learner = StreamLearner(config.method(method), train)
    order = np.random.SeedSequence(config.seed, spawn_key=(seed_index, order_seed))
    rng = np.random.default_rng(order)
    grid = len(tasks)
    chosen, mean, worst = [], [], []
    for round_ in range(options.rounds):
        if round_ == 0:
            index = 0
        elif strategy == "fixed":
            index = round(round_ * (grid - 1) / max(options.rounds - 1, 1))
        elif strategy == "random":
            index = int(rng.integers(grid))
        else:
            index = int(np.argmax(need(strategy, learner, tasks, train.seed, baseline)))
        learner.learn(source.draw(round_, index), boundary=round_ > 0)
        errors = [learner.evaluate(t.test, train.seed + j)["ade"] for j, t in enumerate(tasks)]
        chosen.append(index)
        mean.append(float(np.mean(errors)))
        worst.append(float(np.max(errors)))
    return {"chosen": chosen, "mean": mean, "worst": worst, "final_errors": errors}


def need(strategy: str, learner: StreamLearner, tasks: list[Task], seed: int, baseline) -> list:
    """How much each grid value needs more scenes, by a score-based strategy, on the grid's
    validation sets."""
    if strategy == "spread":
        return [learner.disagreement(t.val, seed + j) for j, t in enumerate(tasks)]
    errors = [learner.evaluate(t.val, seed + j)["ade"] for j, t in enumerate(tasks)]
    if strategy == "relative":
        return [e / b for e, b in zip(errors, baseline, strict=True)]
    return errors


def run_active(
    config: ExperimentConfig,
    options: ActiveOptions,
    cache: Path = Path(".cache/domains"),
    workers: int = 1,
    memory_budget: float | None = None,
) -> dict[str, Any]:
    """Every strategy for the first method of ``config``; the report as a dictionary."""
    specs = grid_specs(config)
    if config.quick:
        options = replace(options, rounds=min(options.rounds, 3), scenes=min(options.scenes, 6))
    tasks, _ = make_tasks(specs, config.seed, config.quick, cache, workers, memory_budget)
    if any(t.val is None for t in tasks):
        raise InputError(f"scenario {config.scenario!r}: every grid value needs validation scenes")
    method = config.methods[0]
    source = SceneSource(specs, options.scenes, config.seed)
    cv = config.method("cv").build_model()
    baseline = [evaluate(cv, t.val, config.k, config.seed + j)["ade"] for j, t in enumerate(tasks)]
    strategies = {}
    count = sum(options.random_orders if s == "random" else 1 for s in options.strategies)
    bar = tqdm(total=count * config.seeds, desc="runs", unit="run", file=sys.stderr, leave=False)
    for strategy in options.strategies:
        orders = options.random_orders if strategy == "random" else 1
        runs = []
        for s in range(config.seeds):
            for order in range(orders):
                args = (config, method, tasks, source, options, s, baseline)
                runs.append(run_strategy(strategy, order, *args))
                bar.update()
        mean, worst = np.array([r["mean"] for r in runs]), np.array([r["worst"] for r in runs])
        strategies[strategy] = {
            "runs": len(runs),
            "chosen": [r["chosen"] for r in runs],
            "mean": mean.mean(0).tolist(),
            "mean_std": mean.std(0).tolist(),
            "worst": worst.mean(0).tolist(),
            "worst_std": worst.std(0).tolist(),
            "final_errors": np.mean([r["final_errors"] for r in runs], axis=0).tolist(),
        }
    bar.close()
    return {
        "scenario": config.scenario,
        "family": specs[0].family.name,
        "knob": specs[0].family.knob,
        "grid": [float(s.value) for s in specs],
        "method": method,
        "rounds": options.rounds,
        "scenes_per_round": options.scenes,
        "scenes": [options.scenes * (r + 1) for r in range(options.rounds)],
        "epochs": config.epochs,
        "seeds": config.seeds,
        "k": config.k,
        "strategies": strategies,
    }


def active_markdown(report: dict[str, Any]) -> str:
    grid = report["grid"]
    lines = [
        f"# Active curriculum on {report['family']} ({report['knob']} {grid[0]:g} to "
        f"{grid[-1]:g}, {len(grid)} values)",
        "",
        f"{report['method']}, {report['rounds']} rounds of {report['scenes_per_round']} new "
        f"scenes, {report['epochs']} epochs a round, {report['seeds']} seed(s). Held-out ADE "
        f"best of {report['k']} over the grid (metres), mean ± std over runs.",
        "",
        "| strategy | runs | final mean ADE | final worst ADE | mean ADE over the rounds | "
        "values chosen (first run) |",
        "|---|---|---|---|---|---|",
    ]
    for name, s in report["strategies"].items():
        chosen = ", ".join(f"{grid[i]:g}" for i in s["chosen"][0])
        lines.append(
            f"| {name} | {s['runs']} | {s['mean'][-1]:.3f} ± {s['mean_std'][-1]:.3f} | "
            f"{s['worst'][-1]:.3f} ± {s['worst_std'][-1]:.3f} | {np.mean(s['mean']):.3f} | "
            f"{chosen} |"
        )
    lines += ["", "Mean / worst held-out ADE after each round:", ""]
    lines.append("| scenes | " + " | ".join(report["strategies"]) + " |")
    lines.append("|---" * (len(report["strategies"]) + 1) + "|")
    for r, scenes in enumerate(report["scenes"]):
        cells = [f"{s['mean'][r]:.3f} / {s['worst'][r]:.3f}" for s in report["strategies"].values()]
        lines.append(f"| {scenes} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def active_figure(report: dict[str, Any], path: Path) -> None:
    """Mean and worst held-out ADE against scenes simulated, and the final error per grid value,
    one line per strategy."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 3, figsize=(15, 3.8))
    for name, s in report["strategies"].items():
        for ax, key in zip(axes[:2], ("mean", "worst"), strict=True):
            ax.errorbar(
                report["scenes"], s[key], s[f"{key}_std"], fmt="-o", ms=3, capsize=2, label=name
            )
        axes[2].plot(report["grid"], s["final_errors"], "-o", ms=3, label=name)
    axes[0].set(xlabel="scenes simulated", ylabel="mean held-out ADE (m)")
    axes[1].set(xlabel="scenes simulated", ylabel="worst held-out ADE (m)")
    axes[2].set(xlabel=report["knob"], ylabel="final held-out ADE (m)")
    axes[0].legend(fontsize=7)
    fig.suptitle(f"active curriculum on {report['family']} ({report['method']})", fontsize=10)
    fig.tight_layout()
    write_atomic(path, lambda tmp: fig.savefig(tmp, dpi=110, format="png"))
    plt.close(fig)


def write_active(report: dict[str, Any], out: Path) -> None:
    """``active.json``, ``active.md`` and ``active.png`` in ``out``."""
    write_report(out, "active", report, active_markdown, active_figure)


@guarded
def main(argv: list[str] | None = None) -> int:
    examples = (
        "  python -m sim.active --scenario crowd_noise_0.1..0.6:0.05 --rounds 8 --scenes 40\n"
        "  python -m sim.active --scenario crowd_radius_0.1..0.6 --strategies error,fixed --quick"
    )
    p = parser("sim.active", __doc__.splitlines()[0], examples)
    p.add_argument("--rounds", type=bounded_int(1, 1000), default=8, help="rounds of new scenes")
    p.add_argument("--scenes", type=bounded_int(1, 100_000), default=40, help="scenes a round")
    p.add_argument("--strategies", default=",".join(STRATEGIES), help="comma-separated")
    p.add_argument("--random-orders", type=bounded_int(1, 100), default=3)
    p.add_argument("--method", default="finetune", help="the learner (default finetune)")
    p.add_argument("--out", type=Path, default=Path("active"), help="folder of the report")
    add_learning_options(p)
    args = parse(p, sys.argv[1:] if argv is None else argv)
    if args is None:
        return 0
    torch.set_num_threads(args.threads)
    config = learning_config(args, (args.method,))
    strategies = tuple(s.strip() for s in args.strategies.split(",") if s.strip())
    options = ActiveOptions(args.rounds, args.scenes, strategies, args.random_orders)
    report = run_active(config, options, args.cache, args.workers, args.memory_budget)
    write_active(report, args.out)
    print(active_markdown(report))
    return 0


if __name__ == "__main__":
    sys.exit(main())
