"""``python -m sim.study active``: an active curriculum simulates where the model fails.

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

from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from c2inet.errors import InputError
from c2inet.lazy import lazy_module
from c2inet.options import check_range
from sim.domains import domain_seed
from sim.generators import child_seed
from sim.scenario import DomainSpec
from sim.studies.base import Study, register
from viz.cli import bounded_int

if TYPE_CHECKING:  # the learner and the engine load once there is work (``sim.studies.base``)
    from c2inet.data import Windows
    from c2inet.stream import StreamLearner
    from c2inet.trainer import Task
    from sim.experiment import Execution, ExperimentConfig

# the learner, the engine and the figures load once there is work (sim.studies.base)
evaluation = lazy_module("c2inet.evaluation")
streaming = lazy_module("c2inet.stream")
engine = lazy_module("sim.experiment")
cell_runs = lazy_module("sim.experiment.cells")
curriculum = lazy_module("sim.experiment.curriculum")
study_figures = lazy_module("viz.study_figures")

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
        twice = sorted({s for s in self.strategies if self.strategies.count(s) > 1})
        if twice:
            raise InputError(f"strategies: {twice[0]!r} is named twice; name each once")


def grid_specs(config: ExperimentConfig) -> list[DomainSpec]:
    """The grid: one numeric family that can simulate single scenes, two values or more."""
    where = f"scenario {config.scenario!r} (an active curriculum's grid)"
    return curriculum.knob_grid(
        config.specs, where, "crowd_noise_0.1..0.6:0.05", single_scenes=True
    )


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
            self.made[round_, index] = curriculum.scene_windows(
                spec.family, [spec.value] * self.scenes, seeds
            )
        return self.made[round_, index]


def run_strategy(
    strategy: str,
    order_seed: int,
    seed_index: int,
    config: ExperimentConfig,
    method: str,
    tasks: list[Task],
    source: SceneSource,
    options: ActiveOptions,
    baseline: list[float],
) -> dict[str, list]:
    """One strategy's rounds (a cell): the values it chose and the held-out errors after each.
    ``baseline``: constant velocity's validation ADE at each grid value."""
    train = replace(config.train_config(seed_index), diagnostics=False, val_every=0)
    learner = streaming.StreamLearner(config.method(method), train)
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
    execution: Execution | None = None,
    folder: Path | None = None,
    resume: bool = False,
) -> dict[str, Any]:
    """Every strategy for the first method of ``config``, its runs as cells on ``execution``
    (kept in ``folder``, if given, for ``resume``); the report as a dictionary."""
    execution = execution or engine.Execution()
    specs = grid_specs(config)
    if config.quick:
        options = replace(options, rounds=min(options.rounds, 3), scenes=min(options.scenes, 6))
    tasks, _ = curriculum.experiment_tasks(specs, config, execution)
    if any(t.val is None for t in tasks):
        raise InputError(f"scenario {config.scenario!r}: every grid value needs validation scenes")
    method = config.methods[0]
    source = SceneSource(specs, options.scenes, config.seed)
    cv = config.method("cv").build_model()
    baseline = [
        evaluation.evaluate(cv, t.val, config.k, config.seed + j)["ade"]
        for j, t in enumerate(tasks)
    ]
    orders = {s: options.random_orders if s == "random" else 1 for s in options.strategies}
    cells = {
        f"{strategy}-seed_{s}-order_{o}": (strategy, o, s)
        for strategy in options.strategies
        for s in range(config.seeds)
        for o in range(orders[strategy])
    }
    data = [w.positions for t in tasks for w in (t.val, t.test)]
    identity = cell_runs.cell_identity("active", config.to_json(), asdict(options), arrays=data)
    shared = (config, method, tasks, source, options, baseline)
    done = cell_runs.run_cells(run_strategy, cells, shared, execution, folder, identity, resume)
    strategies = {
        strategy: strategy_summary(
            [done[name] for name, (chosen, *_) in cells.items() if chosen == strategy]
        )
        for strategy in options.strategies
    }
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


def strategy_summary(runs: list[dict[str, list]]) -> dict[str, Any]:
    """One strategy's runs: the values each chose, and the held-out errors after each round,
    mean and std over the runs."""
    mean, worst = np.array([r["mean"] for r in runs]), np.array([r["worst"] for r in runs])
    return {
        "runs": len(runs),
        "chosen": [r["chosen"] for r in runs],
        "mean": mean.mean(0).tolist(),
        "mean_std": mean.std(0).tolist(),
        "worst": worst.mean(0).tolist(),
        "worst_std": worst.std(0).tolist(),
        "final_errors": np.mean([r["final_errors"] for r in runs], axis=0).tolist(),
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


class Active(Study):
    name = "active"
    examples = (
        "--scenario crowd_noise_0.1..0.6:0.05 --rounds 8 --scenes 40",
        "--scenario crowd_radius_0.1..0.6 --strategies error,fixed --quick",
    )
    one_method = True

    markdown = staticmethod(active_markdown)

    def figure(self, report, path):
        study_figures.active_figure(report, path)

    def add_options(self, p):
        p.add_argument(
            "--rounds", type=bounded_int(1, 1000), default=8, help="rounds of new scenes"
        )
        p.add_argument("--scenes", type=bounded_int(1, 100_000), default=40, help="scenes a round")
        p.add_argument("--strategies", default=",".join(STRATEGIES), help="comma-separated")
        p.add_argument("--random-orders", type=bounded_int(1, 100), default=3)

    def run(self, args, config, execution, out, argv):
        strategies = tuple(s.strip() for s in args.strategies.split(",") if s.strip())
        options = ActiveOptions(args.rounds, args.scenes, strategies, args.random_orders)
        return run_active(config, options, execution, out, args.resume)


register(Active())
