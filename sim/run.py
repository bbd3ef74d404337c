"""``python -m sim.run``: generate a curriculum, train every method through it, report.

Each run gets a fresh folder (``runs/<scenario>/<timestamp>``, ``latest`` beside it) or
``--out``; ``sim.experiment.outputs`` lists what it holds. The work is
``sim.experiment.run_experiment``.
"""

from __future__ import annotations

import shlex
import sys
import time
from pathlib import Path

from c2inet.lazy import lazy_module
from sim.cli import (
    INTERRUPTED,
    add_experiment_options,
    execution_of,
    experiment_options,
    parse,
    parser,
)
from sim.config_file import resolved_config
from viz.cli import guarded
from viz.serve import how_to_open

# loaded on first use: a command that stops at bad input or answers --help does not pay for it
report = lazy_module("c2inet.report")
engine = lazy_module("sim.experiment")
folders = lazy_module("sim.experiment.folders")
scenario_language = lazy_module("sim.scenario")
artefacts = lazy_module("sim.studies.benchmark.artefacts")

EXAMPLES = """\
  python -m sim.run --scenario crowd_noise_0.1..0.6
  python -m sim.run --scenario crowd_radius_0.1..0.6 --methods c2inet-online,ewc,finetune \\
      --seeds 3 --jobs 2
  python -m sim.run --scenario crowd_noise_0.1..0.3 --quick --set c2inet-online.pruning=false \\
      --set data.agents=6
  python -m sim.run --scenario crowd_noise_0.1..0.6 --resume   # continue the latest run"""


def with_tuning(args, options: dict) -> dict:
    """``--tuned-from``: a tuning's settings (and a preset's board sizes) under the user's own."""
    if not args.tuned_from:
        return options
    tasks = len(scenario_language.parse_scenario(args.scenario, list(options["scenarios_dir"])))
    tuned, source = artefacts.tuned_settings(args.tuned_from, options["methods"], tasks)
    given = options["settings"]
    settings = {
        scope: {**tuned.get(scope, {}), **given.get(scope, {})} for scope in {*tuned, *given}
    }
    print(f"--tuned-from {source}: {tuned}", file=sys.stderr)
    return {**options, "settings": settings}


@guarded
def main(argv: list[str] | None = None) -> int:
    p = parser("sim.run", __doc__.splitlines()[0], EXAMPLES)
    add_experiment_options(p)
    p.add_argument("--out", type=Path, help="output folder (default runs/<scenario>/<timestamp>)")
    p.add_argument(
        "--rerun",
        metavar="spawn|connect[=URL]",
        help="also stream live to a viewer: spawn one, or connect to one (default URL "
        "rerun+http://127.0.0.1:9876/proxy)",
    )
    p.add_argument(
        "--tuned-from",
        metavar="PRESET|FILE",
        help="the settings a tuning chose for these methods: a preset's shipped tuning (e.g. "
        "radius), an artefact or a board's tuning.json; --set and --config win over them",
    )
    p.add_argument(
        "--print-config",
        action="store_true",
        help="print the resolved configuration as a --config TOML file and stop",
    )
    argv = sys.argv[1:] if argv is None else argv
    args = parse(p, argv)
    if args is None:
        return 0
    # the learner and the engine load once there is work: --help and a typo answer at once
    config = engine.ExperimentConfig(args.scenario, **with_tuning(args, experiment_options(args)))
    execution = execution_of(args)
    if args.print_config:
        print(resolved_config(config, execution), end="")
        return 0
    out = folders.output_folder(args.scenario, args.out, args.resume)
    started = time.perf_counter()
    try:
        metrics = engine.run_experiment(
            config, out, execution, args.resume, args.overwrite, [*p.prog.split(), *argv]
        )
    except KeyboardInterrupt:
        kept = [a for a in argv if a not in ("--overwrite", "--resume")]
        again = [*kept, *(["--out", str(out)] if args.out is None else []), "--resume"]
        print(
            f"\ninterrupted: finished tasks are kept in {out}; continue with: "
            f"{p.prog} {shlex.join(again)}",
            file=sys.stderr,
        )
        return INTERRUPTED
    print(report.caption(config.k, config.seeds, unit=config.unit))
    print(report.text_table(metrics["methods"], metrics["labels"]))
    print(f"wall time {time.perf_counter() - started:.0f} s; wrote {out}: open report.md")
    if config.record:
        print(f"view it: {how_to_open(out / 'recording.rrd')}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
