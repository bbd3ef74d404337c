"""``python -m sim.run``: generate a curriculum, train every method through it, report.

Each run gets a fresh folder (``runs/<scenario>/<timestamp>``, ``latest`` beside it) or
``--out``; ``sim.outputs`` lists what it holds. The work is ``sim.experiment.run_experiment``.
"""

from __future__ import annotations

import shlex
import sys
import time
from pathlib import Path

from c2inet.backbones import BACKBONES
from c2inet.methods.base import discover
from c2inet.report import caption, text_table
from sim.backends import BACKENDS
from sim.cli import add_threads, add_workers, parse, parser
from sim.experiment import (
    DEFAULT_METHODS,
    Execution,
    ExperimentConfig,
    parse_settings,
    run_experiment,
)
from sim.outputs import output_folder
from viz.cli import bounded_int, guarded

INTERRUPTED = 130  # the shell's code for a run stopped by Ctrl-C
EXAMPLES = """\
  python -m sim.run --scenario crowd_noise_0.1..0.6
  python -m sim.run --scenario crowd_radius_0.1..0.6 --methods c2inet-online,ewc,finetune \\
      --seeds 3 --jobs 2
  python -m sim.run --scenario crowd_noise_0.1..0.3 --quick --set c2inet-online.pruning=false \\
      --set data.agents=6
  python -m sim.run --scenario crowd_noise_0.1..0.6 --resume   # continue the latest run"""


def add_experiment_options(p) -> None:
    """The options ``sim.run`` and ``sim.sweep`` share (besides the scenario)."""
    p.add_argument(
        "--methods",
        default=",".join(DEFAULT_METHODS),
        help=f"comma-separated, or all (default {','.join(DEFAULT_METHODS)})",
    )
    p.add_argument("--backbone", choices=sorted(BACKBONES), default="stgat")
    p.add_argument(
        "--epochs", type=bounded_int(0, 10_000), help="epochs per task (default 20, quick 2)"
    )
    p.add_argument(
        "--seeds", type=bounded_int(1, 100), default=1, help="seeds per method; cells: mean, std"
    )
    p.add_argument(
        "--k", type=bounded_int(1, 1000), help="samples of best-of-K (default 20, quick 5)"
    )
    p.add_argument("--cache", type=Path, default=Path(".cache/domains"), help="domain cache folder")
    p.add_argument("--quick", action="store_true", help="tiny sizes, for smoke tests")
    p.add_argument("--resume", action="store_true", help="continue the run in --out (or latest)")
    p.add_argument("--overwrite", action="store_true", help="replace the run in --out")
    p.add_argument("--backend", choices=BACKENDS, default="local", help="where jobs run")
    p.add_argument(
        "--jobs",
        type=bounded_int(1, 1024),
        default=1,
        help="jobs at once: local processes, or the CPUs of the local Ray cluster (default 1)",
    )
    p.add_argument("--ray-address", help="join this Ray cluster instead of starting one")
    add_workers(p)
    add_threads(p)
    p.add_argument("--no-record", action="store_true", help="do not write recording.rrd")
    p.add_argument(
        "--logger",
        default="",
        help="also log every job's curves: csv, tensorboard or both (comma-separated)",
    )


def add_learning_options(p, methods: str | None = None) -> None:
    """The options of the commands that train in this process (``sim.fidelity``,
    ``sim.drift``, ``sim.active``): what to train, and where the domains are cached.
    ``methods``: the default of ``--methods`` (None: no such option)."""
    if methods is not None:
        p.add_argument("--methods", default=methods, help=f"comma-separated (default {methods})")
    p.add_argument("--backbone", choices=sorted(BACKBONES), default="stgat")
    p.add_argument("--epochs", type=bounded_int(0, 10_000), help="epochs (default 20, quick 2)")
    p.add_argument("--seeds", type=bounded_int(1, 100), default=1, help="seeds per method")
    p.add_argument("--k", type=bounded_int(1, 1000), help="samples of best-of-K (default 20)")
    p.add_argument("--quick", action="store_true", help="tiny sizes, for smoke tests")
    p.add_argument("--set", action="append", default=[], metavar="SCOPE.KEY=VALUE")
    p.add_argument("--cache", type=Path, default=Path(".cache/domains"), help="domain cache")
    add_workers(p)
    add_threads(p)


def learning_config(args, methods: tuple[str, ...], scenario: str | None = None):
    """The ``ExperimentConfig`` of :func:`add_learning_options`' options (no recording)."""
    settings = parse_settings(args.set)
    options = {**_trained(args), "methods": methods, "settings": settings, "record": False}
    return ExperimentConfig(scenario or args.scenario, **options)


def experiment_options(args) -> dict:
    """The fields of ``ExperimentConfig`` given by :func:`add_experiment_options`' options."""
    return {
        "methods": method_names(args.methods),
        **_trained(args),
        "record": not args.no_record,
    }


def method_names(text: str) -> tuple[str, ...]:
    """``--methods``: comma-separated names, or ``all`` for every registered method."""
    if text.strip() == "all":
        return tuple(sorted(discover()))
    return tuple(name.strip() for name in text.split(",") if name.strip())


def _trained(args) -> dict:
    """What both option sets say about the training and the data."""
    return {
        "seeds": args.seeds,
        "seed": args.seed,
        "epochs": args.epochs,
        "k": args.k,
        "backbone": args.backbone,
        "quick": args.quick,
        "scenarios_dir": tuple(args.scenarios_dir),
    }


def execution_of(args) -> Execution:
    return Execution(
        backend=args.backend,
        jobs=args.jobs,
        ray_address=args.ray_address,
        threads=args.threads,
        workers=args.workers,
        memory_budget=args.memory_budget,
        cache=args.cache,
        rerun=getattr(args, "rerun", None),
        loggers=tuple(n.strip() for n in args.logger.split(",") if n.strip()),
    )


@guarded
def main(argv: list[str] | None = None) -> int:
    p = parser("sim.run", __doc__.splitlines()[0], EXAMPLES)
    add_experiment_options(p)
    p.add_argument("--out", type=Path, help="output folder (default runs/<scenario>/<timestamp>)")
    p.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="SCOPE.KEY=VALUE",
        help="override an option: model.beta_c=0, train.lr=0.001, c2inet-online.pruning=false",
    )
    p.add_argument(
        "--rerun",
        metavar="spawn|connect[=URL]",
        help="also stream live to a viewer: spawn one, or connect to one (default URL "
        "rerun+http://127.0.0.1:9876/proxy)",
    )
    argv = sys.argv[1:] if argv is None else argv
    args = parse(p, argv)
    if args is None:
        return 0
    config = ExperimentConfig(
        args.scenario, settings=parse_settings(args.set), **experiment_options(args)
    )
    execution = execution_of(args)
    out = output_folder(args.scenario, args.out, args.resume)
    started = time.perf_counter()
    try:
        metrics = run_experiment(
            config, out, execution, args.resume, args.overwrite, ["python", "-m", "sim.run", *argv]
        )
    except KeyboardInterrupt:
        kept = [a for a in argv if a not in ("--overwrite", "--resume")]
        again = [*kept, *(["--out", str(out)] if args.out is None else []), "--resume"]
        print(
            f"\ninterrupted: finished tasks are kept in {out}; continue with: "
            f"python -m sim.run {shlex.join(again)}",
            file=sys.stderr,
        )
        return INTERRUPTED
    print(caption(config.k, config.seeds))
    print(text_table(metrics["methods"], metrics["labels"]))
    print(f"wall time {time.perf_counter() - started:.0f} s; wrote {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
