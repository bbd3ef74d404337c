"""``python -m sim.bench PRESET``: the fair benchmark, tuning then evaluation then a leaderboard.

Every method gets the same number of Optuna trials over the learning rate and its own knobs,
scored on validation data of a separate tuning curriculum (never a test split, never a value
evaluated), then runs with its chosen settings over seeds that each draw their own data, the
same for every method. The leaderboard ranks the point prediction (K = 1) with 95 % intervals
and Holm-adjusted paired tests against fine-tuning, beside forgetting, memory and CPU cost; the
references (joint, joint from scratch) stand apart. Resumable like a run. The protocol lives in
``sim.studies.benchmark``.
"""

from __future__ import annotations

import sys
from pathlib import Path

from sim.cli import add_experiment_options, execution_of, experiment_options, interrupted, parse
from sim.cli import parser as command_parser
from sim.studies.presets import (
    PRESETS,
    RACE,
    RACE_SEEDS,
    REFERENCE_SEEDS,
    REGISTRY,
    REPLAY_BUDGET,
    SAMPLER,
    SEEDS,
    TRIALS,
)
from viz.cli import bounded_float, bounded_int, guarded


def presets() -> str:
    return "\n".join(
        f"  {name:<9} {p.scenario}  (tuned on {p.tune_scenario}): {p.description}"
        for name, p in REGISTRY.discover().items()
    )


EXAMPLES = (
    "  python -m sim.bench radius --methods all --jobs 2\n"
    "  python -m sim.bench radius --methods all --jobs 2 --resume \\\n"
    "      --compare c2inet-online,finetune   # then seeds until the pair is decided\n"
    "  python -m sim.bench --scenario crowd_noise_0.1..0.3 --methods finetune,ewc \\\n"
    "      --trials 4 --seeds 3 --quick --out benchmarks_out/smoke\n"
)


def add_tuning_options(p) -> None:
    """The tuning's budget, curriculum, seed and storage."""
    g = p.add_argument_group("tuning")
    g.add_argument(
        "--trials",
        type=bounded_int(1, 1000),
        default=TRIALS,
        help=f"tuning trials per method ({TRIALS})",
    )
    g.add_argument(
        "--prune",
        action="store_true",
        help="stop tuning trials worse than the median of the finished ones after a task (from "
        "the second on); cheaper, but it can discard the best trial (docs/runs.md)",
    )
    g.add_argument(
        "--race",
        type=bounded_int(0, 1000),
        default=RACE,
        metavar="TOP",
        help=f"score each method's TOP best trials again on --race-seeds more seeds and choose "
        f"the best mean, not the best single score ({RACE}: off)",
    )
    g.add_argument(
        "--race-seeds",
        type=bounded_int(1, 100),
        default=RACE_SEEDS,
        help=f"the seeds each raced trial gets beyond its own ({RACE_SEEDS})",
    )
    g.add_argument(
        "--sampler",
        default=SAMPLER,
        help=f"what asks the trials after the start-up draws: tpe (Optuna's TPE) or gp (its "
        f"Gaussian process) ({SAMPLER})",
    )
    g.add_argument("--tune-scenario", help="the tuning curriculum (default: the preset's)")
    g.add_argument(
        "--tuning-seed",
        type=bounded_int(0, 2**31 - 1),
        help="the tuning's own root seed (its sampler, trials and data; default --seed): a "
        "second tuning of one benchmark, evaluated on the same seeds, shows whether it selects",
    )
    g.add_argument(
        "--tuned-from",
        type=Path,
        metavar="BOARD",
        help="no tuning: every method's settings as another benchmark chose them (its folder or "
        "tuning.json), e.g. to rank the same settings on another curriculum",
    )
    g.add_argument(
        "--storage",
        help="the trials' Optuna storage: a database URL, or journal:FILE (Optuna's journal, a "
        "file processes on several machines may share); default: SQLite in --out",
    )


def add_evaluation_options(p) -> None:
    """What every method keeps, the references' seeds and the decisive pair."""
    g = p.add_argument_group("evaluation")
    g.add_argument(
        "--replay-budget",
        type=bounded_int(0, 1_000_000),
        default=REPLAY_BUDGET,
        metavar="SCENES",
        help=f"scenes every replay method (coresets, A-GEM, DER++) keeps in all ({REPLAY_BUDGET}; "
        "0: each its own default)",
    )
    g.add_argument(
        "--reference-seeds",
        type=bounded_int(1, 1000),
        default=REFERENCE_SEEDS,
        help=f"seeds of each reference, joint and joint-scratch ({REFERENCE_SEEDS})",
    )
    g.add_argument(
        "--compare",
        metavar="A,B",
        help="the decisive pair: add seeds to these two until the 95 %% interval of their "
        "paired difference is narrower than --width",
    )
    g.add_argument(
        "--width",
        type=bounded_float(1e-6, 1.0),
        default=0.01,
        metavar="METRES",
        help="the decisive pair's interval width to reach (0.01 m)",
    )
    g.add_argument(
        "--max-seeds",
        type=bounded_int(2, 1000),
        default=30,
        help="the decisive pair's most seeds (30)",
    )


def bench_parser():
    """The command's options: a run's, the tuning's and the evaluation's."""
    p = command_parser("sim.bench", __doc__.splitlines()[0], EXAMPLES + f"presets:\n{presets()}")
    p.add_argument("preset", nargs="?", help=f"one of {', '.join(PRESETS)} (or --scenario)")
    add_experiment_options(p, methods="all", record=True)
    p.set_defaults(seeds=SEEDS)
    add_tuning_options(p)
    add_evaluation_options(p)
    p.add_argument("--out", type=Path, help="the benchmark's folder (default bench/PRESET)")
    p.add_argument(
        "--estimate",
        action="store_true",
        help="time one trial and one job of every method on this machine, print what the "
        "benchmark would cost, and stop (writes nothing)",
    )
    return p


@guarded
def main(argv: list[str] | None = None) -> int:
    p = bench_parser()
    argv = sys.argv[1:] if argv is None else argv
    args = parse(p, argv, scenario_required=False)
    if args is None:
        return 0
    if (args.preset is None) == (args.scenario is None):
        p.error("give a preset or --scenario (one of them)")
    preset = None
    if args.preset is not None:
        preset = REGISTRY.get(args.preset)
        args.scenario = preset.scenario
    out = args.out or Path("bench") / (args.preset or "custom")
    from sim.experiment import ExperimentConfig  # the engine loads once there is work
    from sim.studies.bench_config import BenchConfig
    from sim.studies.bench_estimate import estimate_bench, estimate_table
    from sim.studies.benchmark import run_bench
    from sim.studies.leaderboard import leaderboard_markdown

    bench = BenchConfig(
        ExperimentConfig(args.scenario, **experiment_options(args)),
        args.preset or "custom",
        args.tune_scenario or (preset.tune_scenario if preset else None),
        args.trials,
        args.storage,
        args.replay_budget or None,
        args.prune,
        args.reference_seeds,
        tuple(args.compare.split(",")) if args.compare else (),
        args.width,
        args.max_seeds,
        preset.data if preset else {},
        args.tuning_seed,
        args.race,
        args.race_seeds,
        args.sampler,
        args.tuned_from,
    )
    if args.estimate:
        print(estimate_table(bench, estimate_bench(bench, execution_of(args))))
        return 0
    try:
        board = run_bench(
            bench, out, execution_of(args), args.resume, args.overwrite, [*p.prog.split(), *argv]
        )
    except KeyboardInterrupt:
        return interrupted(out)
    print(leaderboard_markdown(board))
    print(f"wrote {out}: open leaderboard.md; every number in results.parquet", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
