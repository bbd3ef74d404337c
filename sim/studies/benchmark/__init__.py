"""``python -m sim.study bench PRESET``: the fair benchmark, tuning then evaluation then a
leaderboard (``python -m sim.bench PRESET`` and ``c2i-bench`` run the same study).

Every method gets the same number of Optuna trials over the learning rate and its own knobs,
scored on validation data of a separate tuning curriculum (never a test split, never a value
evaluated), then runs with its chosen settings over seeds that each draw their own data, the
same for every method. The leaderboard ranks the point prediction (K = 1) with 95 % intervals
and Holm-adjusted paired tests against fine-tuning, beside forgetting, memory and CPU cost; the
references (joint, joint from scratch) stand apart. Resumable like a run.

This module declares the study (its options; light, so listing the studies loads no learner);
the package's other modules hold the benchmark: ``presets`` (the protocol's sizes and
presets), ``config`` (what is tuned and evaluated, its storage key), ``estimate`` (its cost),
``protocol`` (the run) and ``leaderboard`` (the ranking and its table).
"""

from __future__ import annotations

import sys
from pathlib import Path

from c2inet.errors import InputError
from c2inet.lazy import lazy_module
from sim.studies.base import Study, register
from sim.studies.benchmark.presets import (
    BATCH,
    PRESETS,
    RACE,
    RACE_SEEDS,
    REFERENCE_SEEDS,
    REGISTRY,
    REPLAY_BUDGET,
    SAMPLER,
    SEEDS,
    TRIALS,
    Preset,
)
from viz.cli import bounded_float, bounded_int

# loaded on first use: a command that stops at bad input or answers --help does not pay for it
designs = lazy_module("sim.experiment.design")
artefacts = lazy_module("sim.studies.benchmark.artefacts")
board_markdown = lazy_module("sim.studies.benchmark.board_markdown")
bench_config = lazy_module("sim.studies.benchmark.config")
bench_estimate = lazy_module("sim.studies.benchmark.estimate")
bench_protocol = lazy_module("sim.studies.benchmark.protocol")

__all__ = ["BATCH", "PRESETS", "REFERENCE_SEEDS", "REPLAY_BUDGET", "SEEDS", "TRIALS", "Preset"]


def presets() -> str:
    """One line a preset: its curriculum, its tuning curriculum and what it stands for."""
    return "\n".join(
        f"  {name:<9} {p.scenario}  (tuned on {p.tune_scenario}): {p.description}"
        for name, p in REGISTRY.discover().items()
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
        "--storage",
        help="the trials' Optuna storage: a database URL, or journal:FILE (Optuna's journal, a "
        "file processes on several machines may share); default: SQLite in --out",
    )


def add_artefact_options(p) -> None:
    """Where a board's settings come from: the preset's shipped tuning, another's, or anew."""
    g = p.add_argument_group("shipped tuning")
    g.add_argument(
        "--tuned-from",
        type=Path,
        metavar="FILE",
        help="no tuning: every method's settings from this file (a tuning artefact, a board's "
        "folder or tuning.json) instead of the preset's shipped tuning, e.g. to rank the same "
        "settings on another curriculum",
    )
    g.add_argument(
        "--retune",
        action="store_true",
        help="tune anew (a preset's board evaluates its shipped tuning artefact by default)",
    )
    g.add_argument(
        "--tune-only",
        action="store_true",
        help="tune and write the tuning artefact (OUT/PRESET.json, the file a preset ships), "
        "no evaluation; resumable with --resume",
    )
    g.add_argument(
        "--design",
        choices=("staged", "optuna"),
        help="how a tuning chooses: staged (a preset's own grid of learning rates, then each "
        "knob in turn, every setting on the same data draws; a preset's default) or optuna "
        "(--trials Optuna trials, one data draw each; the default with --scenario)",
    )
    g.add_argument(
        "--design-offset",
        type=bounded_float(-0.99, 0.99),
        metavar="STEPS",
        help="move the staged design's grids by this share of a step (a second design)",
    )
    g.add_argument(
        "--keep-defaults",
        choices=("mean", "every-draw"),  # sim.experiment.design.KEEP_RULES, not imported by --help
        help="when the staged design keeps a method's defaults over its walk's choice: "
        "every-draw (lower on each draw; the default) or mean (a lower mean over the draws, "
        "as every shipped tuning was made)",
    )


def add_evaluation_options(p) -> None:
    """What every method keeps, the references' seeds and the decisive pair."""
    g = p.add_argument_group("evaluation")
    g.add_argument(
        "--metric",
        choices=("ade_k1", "ade"),  # c2inet.report.RANKABLE, not imported by --help
        help="what the board ranks and its tuning scores: ade_k1, the point prediction's final "
        "ADE, or ade, the best of K (default: the preset's; eth-ucy ranks ade, the published "
        "protocol there)",
    )
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


class Benchmark(Study):
    """The fair benchmark as a study: the skeleton parses and configures it; the protocol claims
    its folder (after checking the tuning storage), tunes, evaluates and writes the board."""

    name = "bench"
    title = "the fair benchmark, tuning then evaluation then a leaderboard"
    examples = (
        "radius --methods all --jobs 2",
        "radius --methods all --jobs 2 --resume --compare c2inet-online,finetune",
        "--scenario crowd_noise_0.1..0.3 --methods finetune,ewc --trials 4 --seeds 3 --quick "
        "--out benchmarks_out/smoke",
    )
    methods = "all"
    sweeps = True  # its jobs are the engine's runs (--logger, --no-record); it claims its folder
    scenario_required = False  # a preset names it
    report = "leaderboard"

    def add_options(self, p):
        p.add_argument("preset", nargs="?", help=f"one of {', '.join(PRESETS)} (or --scenario)")
        p.set_defaults(seeds=SEEDS)
        add_artefact_options(p)
        add_tuning_options(p)
        add_evaluation_options(p)
        p.add_argument(
            "--estimate",
            action="store_true",
            help="time one trial and one job of every method on this machine, print what the "
            "benchmark would cost, and stop (writes nothing)",
        )
        p.epilog += f"\n\npresets:\n{presets()}"

    def preset(self, args) -> Preset | None:
        """The preset named on the command line (None with ``--scenario``)."""
        if (args.preset is None) == (args.scenario is None):
            raise InputError("give a preset or --scenario (one of them)")
        return None if args.preset is None else REGISTRY.get(args.preset)

    def scenario_of(self, args) -> str:
        preset = self.preset(args)
        return preset.scenario if preset else args.scenario

    folder = "bench/PRESET"

    def default_out(self, args) -> Path:
        return Path("bench") / (args.preset or "custom")

    def run(self, args, config, execution, out, argv):
        preset = self.preset(args)
        tuned_from, design = self.tuning_source(args, preset)
        bench = bench_config.BenchConfig(
            config,
            name=args.preset or "custom",
            # a tuning that ran elsewhere says its own curriculum (--tuned-from, shipped)
            tune_scenario=None
            if tuned_from
            else args.tune_scenario or (preset.tune_scenario if preset else None),
            trials=args.trials,
            storage=args.storage,
            replay_budget=args.replay_budget or None,
            prune=args.prune,
            reference_seeds=args.reference_seeds,
            compare=tuple(args.compare.split(",")) if args.compare else (),
            width=args.width,
            max_seeds=args.max_seeds,
            data=preset.data if preset else {},
            tuning_seed=args.tuning_seed,
            race=args.race,
            race_seeds=args.race_seeds,
            sampler=args.sampler,
            tuned_from=tuned_from,
            design=design,
            metric=args.metric or (preset.metric if preset else "ade_k1"),
            recipe=preset.recipe if preset else {},
        )
        if bench.borrowed:  # say what is taken from another board, method by method
            for method, chosen in bench.borrowed[0].items():
                applied = [f"{s}.{k}={v}" for s, values in chosen["settings"].items()
                           for k, v in values.items()] or ["its defaults"]  # fmt: skip
                print(f"--tuned-from: {method}: {', '.join(applied)}", file=sys.stderr)
        if args.estimate:
            print(
                bench_estimate.estimate_table(
                    bench, bench_estimate.estimate_bench(bench, execution)
                )
            )
            return None
        if args.tune_only:
            bench_protocol.run_bench(
                bench, out, execution, args.resume, args.overwrite, argv, tune_only=True
            )
            return None
        return bench_protocol.run_bench(bench, out, execution, args.resume, args.overwrite, argv)

    def tuning_source(self, args, preset: Preset | None):
        """Where the settings come from: (``--tuned-from`` or the preset's shipped artefact,
        None) when the board only evaluates; (None, the design) when it tunes (``--retune``,
        ``--tune-only``, a custom scenario, a preset that ships none)."""
        tunes = args.retune or args.tune_only
        if args.tuned_from is not None and tunes:
            raise InputError("--tuned-from takes settings, --retune and --tune-only make them")
        artefact = args.tuned_from or (
            artefacts.shipped(preset.name) if preset and not tunes else None
        )
        if artefact is not None:
            tuning = [f for f, given in self.tuning_flags(args) if given]
            if tuning:
                whose = f"the {preset.name} board" if preset else "the board"
                how = "drop --tuned-from" if args.tuned_from else "add --retune"
                raise InputError(
                    f"{', '.join(tuning)}: {whose} evaluates the tuning in {artefact}, tuned "
                    f"already; {how} to tune anew"
                )
            return artefact, None
        kind = args.design or ("staged" if preset else "optuna")
        if kind == "optuna":
            if args.design_offset is not None:
                raise InputError("--design-offset moves the staged design's grids; not optuna's")
            if args.keep_defaults is not None:
                raise InputError("--keep-defaults is the staged design's rule; not optuna's")
            return None, None
        design = preset.design if preset else designs.Design()
        if args.design_offset is not None:
            design = design.shifted(args.design_offset)
        if args.keep_defaults is not None:
            design = design.keeping(args.keep_defaults)
        return None, design

    @staticmethod
    def tuning_flags(args) -> list[tuple[str, bool]]:
        """The tuning options and whether each was given."""
        return [
            ("--trials", args.trials != TRIALS),
            ("--prune", args.prune),
            ("--race", args.race != RACE),
            ("--sampler", args.sampler != SAMPLER),
            ("--tune-scenario", args.tune_scenario is not None),
            ("--tuning-seed", args.tuning_seed is not None),
            ("--design", args.design is not None),
            ("--design-offset", args.design_offset is not None),
            ("--keep-defaults", args.keep_defaults is not None),
            ("--storage", args.storage is not None),
        ]

    def markdown(self, report):
        return board_markdown.leaderboard_markdown(report)

    def write(self, report, out) -> str:
        """The protocol wrote the board (``leaderboard.*`` and ``results.parquet``) itself."""
        return self.report


register(Benchmark())
