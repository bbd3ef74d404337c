"""``python -m sim.sweep``: the cross product of scenarios, methods, seeds and option values.

Every (scenario, setting) is one experiment in its own folder ``<out>/<scenario>/<setting>``
(``sim.run``'s outputs, recording included); all their jobs run together on one backend, and
the sweep is resumable like a run. ``results.parquet`` holds every number in tidy form
(scenario, method, seed, setting, after_task, on_task, metric, value) and ``report.md`` the
final scores, mean and std over seeds. ``--set KEY=V1,V2`` sweeps an option over its values.
"""

from __future__ import annotations

import sys
from pathlib import Path

from c2inet.lazy import lazy_module
from sim.cli import (
    add_experiment_options,
    execution_of,
    experiment_options,
    interrupted,
    parse,
    parser,
)
from viz.cli import guarded

# loaded on first use: a command that stops at bad input or answers --help does not pay for it
engine = lazy_module("sim.experiment")
sweeping = lazy_module("sim.experiment.sweep")


@guarded
def main(argv: list[str] | None = None) -> int:
    examples = (
        "  python -m sim.sweep --scenario crowd_noise_0.1..0.6 \\\n"
        "      --scenario crowd_radius_0.1..0.6 --methods c2inet-online,finetune --seeds 3 \\\n"
        "      --set train.lr=0.003,0.001 --jobs 2 --out sweeps/lr"
    )
    p = parser("sim.sweep", __doc__.splitlines()[0], examples, scenarios=True)
    add_experiment_options(p, grid=True)
    p.add_argument("--out", type=Path, help="the sweep's folder (required)")
    argv = sys.argv[1:] if argv is None else argv
    args = parse(p, argv)
    if args is None:
        return 0
    if args.out is None:
        p.error("the following arguments are required: --out")
    base = engine.ExperimentConfig(args.scenario[0], **experiment_options(args, grid=True))
    sweep = sweeping.SweepConfig(base, tuple(args.scenario), sweeping.parse_grid(args.set))
    try:
        entries = sweeping.run_sweep(
            sweep,
            args.out,
            execution_of(args),
            args.resume,
            args.overwrite,
            [*p.prog.split(), *argv],
        )
    except KeyboardInterrupt:
        return interrupted(args.out)
    print(sweeping.combined_report(entries))
    print(f"wrote {args.out}: open report.md; every number in results.parquet", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
