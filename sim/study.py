"""``python -m sim.study NAME``: run one study of ``sim.studies`` into ``studies/NAME``.

Every study takes the shared options of the commands that train (``sim.cli``) and its own; it
writes ``NAME.md`` (its table), ``NAME.json`` and ``NAME.png`` into ``--out`` (default
``studies/NAME``), a folder that holds nothing else or an earlier output of ours
(``--overwrite``). ``python -m sim.study`` alone lists the studies.
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
from sim.studies.base import Study, discover, get_study
from viz.cli import guarded

# loaded on first use: a command that stops at bad input or answers --help does not pay for it
engine = lazy_module("sim.experiment")
folders = lazy_module("sim.experiment.folders")


def listing() -> str:
    studies = discover()
    rows = [f"  {name:9} {study.title}" for name, study in studies.items()]
    return "usage: python -m sim.study NAME [options]   (NAME --help for its options)\n\n" + (
        "studies:\n" + "\n".join(rows)
    )


def study_parser(study: Study, prog: str | None = None):
    """``study``'s options, the shared ones first; ``prog``: the command that runs it (default
    ``sim.study NAME``)."""
    prog = prog or f"sim.study {study.name}"
    examples = "\n".join(f"  python -m {prog} {e}" for e in study.examples)
    p = parser(prog, study.title, examples, scenarios=study.scenarios)
    record = study.sweeps and study.records
    add_experiment_options(p, study.methods, record=record, loggers=study.sweeps)
    p.add_argument("--out", type=Path, help=f"the study's folder (default {study.folder})")
    study.add_options(p)
    return p


def run_study(study: Study, argv: list[str], prog: str | None = None) -> int:
    """Parse ``argv`` for ``study``, run it, write its three files and say where they are."""
    p = study_parser(study, prog)
    args = parse(p, argv, study.scenario_required)
    if args is None:
        return 0
    options = experiment_options(args)
    if study.one_method and len(options["methods"]) != 1:
        p.error(f"--methods: {study.name} trains one method, got {args.methods!r}")
    config = engine.ExperimentConfig(study.scenario_of(args), **options)
    execution = execution_of(args)
    out = args.out or study.default_out(args)
    if not study.sweeps:  # a study of sweeps claims its folder as a sweep
        folders.claim(out, config, execution, args.resume, args.overwrite)
    try:
        report = study.run(args, config, execution, out, [*p.prog.split(), *argv])
    except KeyboardInterrupt:
        return interrupted(out)
    if report is None:
        return 0
    name = study.write(report, out)
    print(study.markdown(report))
    print(f"wrote {out}: open {name}.md (the table) and {name}.png; {name}.json", file=sys.stderr)
    return 0


@guarded
def main(argv: list[str] | None = None, name: str | None = None, prog: str | None = None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    if name is None:
        if not argv or argv[0] in ("-h", "--help"):
            print(listing())
            return 0 if argv else 2
        name, argv = argv[0], argv[1:]
    return run_study(get_study(name), argv, prog)


def command(name: str, prog: str | None = None):
    """The console script of one study (``c2i-fidelity`` and friends); ``prog``: the module it
    also runs as (``sim.bench``)."""

    def run(argv: list[str] | None = None) -> int:
        return main(argv, name, prog)

    return run


fidelity, drift, shift, active = (command(n) for n in ("fidelity", "drift", "shift", "active"))


if __name__ == "__main__":
    sys.exit(main())
