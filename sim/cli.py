"""What `sim`'s entry points share: the scenario options, ``--list``, workers and threads."""

from __future__ import annotations

import argparse
import dataclasses
import os
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any

from c2inet.errors import InputError, did_you_mean
from c2inet.lazy import lazy_module
from sim.config_file import config_defaults
from sim.experiment.backends import BACKENDS
from sim.experiment.defaults import DEFAULT_METHODS
from sim.families import DATA_ROOT_ENV, available_families, load_family
from sim.generators import get_generator
from viz.cli import bounded_float, bounded_int, config_path, plain_parser

if TYPE_CHECKING:
    from sim.experiment.config import Execution

# loaded on first use: a command that stops at bad input or answers --help does not pay for it
backbones_base = lazy_module("c2inet.backbones.base")
methods_base = lazy_module("c2inet.methods.base")
engine_config = lazy_module("sim.experiment.config")
generators_base = lazy_module("sim.generators.base")
studies_base = lazy_module("sim.studies.base")
bench_presets = lazy_module("sim.studies.benchmark.presets")
viz_loggers = lazy_module("viz.loggers")

SCENARIO_HELP = """scenarios: FAMILY_VALUES, parts joined by '+'; VALUES is a..b (step from the
decimals of a), a..b:step, or v1,v2,... (names for real-data families), e.g.
  crowd_noise_0.1..0.6   crowd_density_0.05..0.30:0.05   eth_ucy_eth,hotel
  crowd_noise_0.1..0.3+crowd_radius_0.2
see what exists with --list families, --list methods, --list knobs FAMILY"""


def parser(
    prog: str, description: str, examples: str = "", scenarios: bool = False
) -> argparse.ArgumentParser:
    """An argument parser with the options every scenario entry point takes, ``--list``, and
    ``examples`` under the help (``scenarios``: ``--scenario`` may be repeated, giving a list).
    Parse with :func:`parse`."""
    p = plain_parser(command_name(prog), description)
    p.formatter_class = argparse.RawDescriptionHelpFormatter
    p.epilog = f"examples:\n{examples}\n\n{SCENARIO_HELP}" if examples else SCENARIO_HELP
    p.add_argument(
        "--scenario",
        action="append" if scenarios else "store",
        help="curriculum, e.g. crowd_noise_0.1..0.6" + (" (repeatable)" if scenarios else ""),
    )
    p.add_argument(
        "--list",
        nargs="+",
        metavar="WHAT",
        help="print what exists and stop: families, methods, backbones, generators, studies, "
        "loggers, presets, or knobs FAMILY",
    )
    p.add_argument(
        "--seed", type=bounded_int(0, 2**63 - 1), default=0, help="root seed (default 0)"
    )
    p.add_argument(
        "--scenarios-dir",
        type=Path,
        action="append",
        default=[],
        help="extra folder of family TOML files (repeatable)",
    )
    p.add_argument(
        "--data-root",
        type=Path,
        metavar="DIR",
        help=f"folder of the datasets that cannot ship (SDD, TrajNet++; default ${DATA_ROOT_ENV})",
    )
    p.add_argument(
        "--config",
        type=Path,
        metavar="FILE",
        help="options from a TOML file or a run's config.json; flags given override it",
    )
    return p


def add_workers(p: argparse.ArgumentParser) -> None:
    """``--workers``: processes that generate episodes in parallel (same result for any count);
    ``--memory-budget``: the most memory one domain's generation may take."""
    p.add_argument(
        "--workers",
        type=bounded_int(1, 256),
        default=os.cpu_count() or 1,
        help="worker processes for episode generation (default: the number of cores)",
    )
    p.add_argument(
        "--memory-budget",
        type=bounded_float(0.001, 1e6),
        default=default_memory_budget(),
        metavar="GB",
        help="refuse a domain whose generation needs more (default: half of this machine's "
        f"memory, {default_memory_budget():g})",
    )


def default_memory_budget() -> float:
    """Half of this machine's memory, in GB."""
    return round(os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES") / 2e9, 1)


def add_threads(p: argparse.ArgumentParser) -> None:
    """``--threads``: torch intra-op threads. One by default: on small machines torch's default
    made the project's small models 8 to 34 times slower whenever another process ran."""
    p.add_argument(
        "--threads",
        type=bounded_int(1, 256),
        default=1,
        help="torch intra-op threads (default 1; more only helps an otherwise idle machine)",
    )


def parse(
    p: argparse.ArgumentParser, argv: list[str], scenario_required: bool = True
) -> argparse.Namespace | None:
    """Parse ``argv`` over the options of ``--config FILE``, if given; for ``--list``, print the
    listing and return None."""
    path = config_path(argv)
    notes: list[str] = []  # said once the command line holds: an error is its only line
    defaults, settings = config_defaults(path, p, notes) if path is not None else ({}, {})
    repeatable = {a.dest for a in p._actions if isinstance(a, argparse._AppendAction)}
    p.set_defaults(**{d: v for d, v in defaults.items() if d not in repeatable})
    args = p.parse_args(argv)
    for dest in repeatable & set(defaults):  # the file's, unless the flag was given
        if not getattr(args, dest):
            value = defaults[dest]
            setattr(args, dest, value if isinstance(value, list) else [value])
    args.config_settings = settings
    if args.data_root is not None:  # through the environment, so every job's process reads it
        if not args.data_root.is_dir():
            raise InputError(f"--data-root {args.data_root}: not a folder")
        os.environ[DATA_ROOT_ENV] = str(args.data_root.resolve())
    if args.list:
        print(listing(args.list, args.scenarios_dir))
        return None
    if scenario_required and not args.scenario:
        p.error("the following arguments are required: --scenario")
    for note in notes:
        print(note, file=sys.stderr)
    return args


def listing(what: list[str], extra_dirs: list[Path]) -> str:
    """The families, the methods, or one family's knobs, as plain text."""
    kind, rest = what[0], what[1:]
    families = available_families(extra_dirs)
    if kind == "families" and not rest:
        rows = []
        for name, path in sorted(families.items()):
            family = load_family(path)
            sets = family.knob or "scene names: " + ",".join(family.value_names)
            rows.append(f"{name:18} {family.generator:8} {sets:18} {family.description}")
        return "\n".join(rows)
    if kind in registries() and not rest:
        return registries()[kind].describe()
    if kind == "knobs" and len(rest) == 1:
        name = rest[0]
        if name not in families:
            raise InputError(f"--list knobs {name}: unknown family{did_you_mean(name, families)}")
        family = load_family(families[name])
        sets = family.knob or "the files of each scene name"
        lines = [
            f"family {name}: generator {family.generator}; the scenario's values set {sets}",
            "knobs (the family's default, else the generator's); change with --set data.KNOB=V",
        ]
        for f in dataclasses.fields(get_generator(family.generator).Knobs):
            default = family.defaults.get(f.name, f.default)
            mark = "  <- the scenario's values" if f.name == family.knob else ""
            lines.append(f"  {f.name:16} {default!r}{mark}")
        splits = dataclasses.asdict(family.splits)
        lines.append(f"scenes per split: {splits} (--set data.splits.train=N, ...)")
        return "\n".join(lines)
    kinds = ", ".join(["families", *registries()])
    raise InputError(f"--list {' '.join(what)}: expected {kinds}, or knobs FAMILY")


def registries() -> dict[str, Any]:
    """Every extension point's registry by the word ``--list`` takes."""
    return {
        "methods": methods_base.REGISTRY,
        "backbones": backbones_base.REGISTRY,
        "generators": generators_base.REGISTRY,
        "studies": studies_base.REGISTRY,
        "loggers": viz_loggers.REGISTRY,
        "presets": bench_presets.REGISTRY,
    }


def add_experiment_options(
    p: argparse.ArgumentParser,
    methods: str = ",".join(DEFAULT_METHODS),
    grid: bool = False,
    record: bool = True,
    loggers: bool = True,
) -> None:
    """The options of every command that trains: what to train (:func:`add_training_options`)
    and where and how its jobs run (:func:`add_execution_options`)."""
    add_training_options(p, methods, grid)
    add_execution_options(p, record, loggers)


def add_training_options(p: argparse.ArgumentParser, methods: str, grid: bool = False) -> None:
    """What to train: methods, backbone, sizes, ``--set`` (``grid``: it lists values to sweep)
    and the device. ``methods``: the default of ``--methods``."""
    p.add_argument(
        "--methods", default=methods, help=f"comma-separated, or all (default {methods})"
    )
    p.add_argument(
        "--backbone", default="stgat", help="stgat (default), stgcnn, or another registered one"
    )
    p.add_argument(
        "--epochs", type=bounded_int(0, 10_000), help="epochs per task (default 20, quick 2)"
    )
    p.add_argument(
        "--seeds", type=bounded_int(1, 100), default=1, help="seeds per method; cells: mean, std"
    )
    p.add_argument(
        "--k", type=bounded_int(1, 1000), help="samples of best-of-K (default 20, quick 5)"
    )
    p.add_argument("--quick", action="store_true", help="tiny sizes, for smoke tests")
    p.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="SCOPE.KEY=V1,V2" if grid else "SCOPE.KEY=VALUE",
        help="an option and the values to sweep, e.g. model.beta_c=0,1 (repeatable: product)"
        if grid
        else "override an option: model.beta_c=0, train.lr=0.001, c2inet-online.pruning=false",
    )
    p.add_argument(
        "--device",
        default="cpu",
        help="where models train: cpu (default), cuda, cuda:N, mps, or auto (a GPU if any)",
    )


def add_execution_options(p: argparse.ArgumentParser, record: bool, loggers: bool) -> None:
    """Where and how jobs run: the domain cache, ``--overwrite``, ``--resume``, workers and
    threads, the backend and ``--jobs``; with ``record`` (the jobs write recordings)
    ``--no-record``, with ``loggers`` (they are the engine's runs) ``--logger``."""
    p.add_argument("--cache", type=Path, default=Path(".cache/domains"), help="domain cache folder")
    p.add_argument("--overwrite", action="store_true", help="replace the output folder (ours only)")
    add_workers(p)
    add_threads(p)
    p.add_argument("--resume", action="store_true", help="continue the run in --out (or latest)")
    p.add_argument("--backend", choices=BACKENDS, default="local", help="where jobs run")
    p.add_argument(
        "--jobs",
        type=bounded_int(1, 1024),
        default=1,
        help="jobs at once: local processes, or the CPUs of the local Ray cluster (default 1)",
    )
    p.add_argument("--ray-address", help="join this Ray cluster instead of starting one")
    if record:
        p.add_argument("--no-record", action="store_true", help="do not write recording.rrd")
    if loggers:
        p.add_argument(
            "--logger",
            default="",
            help="also log every job's curves: csv, tensorboard, mlflow (the run's own "
            "mlflow.db store), mlflow=URI (a tracking server), wandb (offline, in each job's "
            "folder) or wandb=online; comma-separated",
        )


def experiment_options(args: argparse.Namespace, grid: bool = False) -> dict:
    """The fields of ``ExperimentConfig`` that :func:`add_experiment_options`' options give
    (``grid``: ``--set`` is a sweep's grid, not the configuration's settings). Settings of a
    ``--config`` file come first; ``--set`` overrides them key by key."""
    settings = {scope: dict(values) for scope, values in args.config_settings.items()}
    for scope, values in ({} if grid else engine_config.parse_settings(args.set)).items():
        settings.setdefault(scope, {}).update(values)
    return {
        "methods": method_names(args.methods),
        "seeds": args.seeds,
        "seed": args.seed,
        "epochs": args.epochs,
        "k": args.k,
        "backbone": args.backbone,
        "quick": args.quick,
        "scenarios_dir": tuple(args.scenarios_dir),
        "settings": settings,
        "record": not getattr(args, "no_record", True),
        "device": args.device,
    }


def method_names(text: str) -> tuple[str, ...]:
    """``--methods``: comma-separated names, or ``all`` for every registered method."""
    if text.strip() == "all":
        return tuple(sorted(methods_base.discover()))
    return tuple(name.strip() for name in text.split(",") if name.strip())


def execution_of(args: argparse.Namespace) -> Execution:
    """How the command's experiment runs, from :func:`add_experiment_options`' options (the
    job options a command lacks keep ``Execution``'s defaults)."""
    names = (
        "backend",
        "jobs",
        "ray_address",
        "threads",
        "workers",
        "memory_budget",
        "cache",
        "rerun",
    )
    options = {name: getattr(args, name) for name in names if hasattr(args, name)}
    loggers = getattr(args, "logger", "")
    return engine_config.Execution(
        **options, loggers=tuple(n.strip() for n in loggers.split(",") if n.strip())
    )


def command_name(module: str) -> str:
    """The command as the user typed it: ``c2i-run`` from the console script, else
    ``python -m MODULE``."""
    invoked = Path(sys.argv[0]).name
    return invoked if invoked.startswith("c2i-") else f"python -m {module}"


def interrupted(out: Path) -> int:
    """Tell what a Ctrl-C kept; the shell's exit code of an interrupted command."""
    print(f"\ninterrupted: add --resume to continue in {out}", file=sys.stderr)
    return INTERRUPTED


INTERRUPTED = 130  # the shell's code for a command stopped by Ctrl-C
