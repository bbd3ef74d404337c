"""``python -m sim.run``: generate a curriculum, train every method through it, report.

Writes under ``runs/<scenario>/`` (or ``--out``): ``run_card.json`` (resolved configuration,
versions, data hashes), ``report.md``, ``matrices/*.csv``, ``checkpoints/``, and ``metrics.json``,
the machine-readable contract (per method: best-of-K joint ``ade``/``fde``, single-sample
``ade_k1``/``fde_k1``, ``avg_seen_ade``, ``forgetting_final_ade`` and ``forgetting_worst_ade``,
``diagnostics``, ``seeds``; row i is after task i).
"""

from __future__ import annotations

import json
import platform
import re
import sys
import time
from dataclasses import asdict, replace
from importlib import metadata
from pathlib import Path
from typing import Any

import numpy as np
import torch
from tqdm import tqdm

from c2inet.backbones import BACKBONES
from c2inet.errors import InputError
from c2inet.files import write_text_atomic
from c2inet.methods.base import build_options, get_method
from c2inet.model import ModelConfig
from c2inet.report import (
    markdown_report,
    matrix_csv,
    summarise,
    summarise_diagnostics,
    text_table,
)
from c2inet.trainer import ContinualTrainer, Task, TrainConfig
from sim.cli import add_threads, add_workers, bounded_int, guarded, parser
from sim.data import SPLITS, cut_windows, window_members
from sim.domains import build_domain, rollout_scene
from sim.families import Splits
from sim.generate import domain_summary
from sim.generators import get_generator
from sim.scenario import DomainSpec, parse_scenario
from viz import figures
from viz.observer import RecordingObserver, Showcase, log_truth
from viz.recording import RunRecorder, default_blueprint

DEFAULT_METHODS = "c2inet-online,finetune,cv"
QUICK_WINDOWS = 24  # at most this many windows per split in --quick runs (real data)
SAMPLE_SCENES = 4  # test scenes per task drawn in the recording
ROLLOUT_FRAMES = 50  # frames of the longer episode played per domain (20 s at 0.4 s)


def run_folder(scenario: str) -> Path:
    """``runs/<scenario>`` with every character outside [A-Za-z0-9._,+-] replaced by '_'."""
    name = re.sub(r"[^A-Za-z0-9._,+-]", "_", scenario).strip(".") or "scenario"
    return Path("runs") / name


def make_tasks(
    curriculum: list[DomainSpec], seed: int, quick: bool, cache: Path, workers: int
) -> tuple[list[Task], list]:
    """Domains of the curriculum as learner tasks (windows per split)."""
    tasks, domains = [], []
    for spec in tqdm(curriculum, desc="domains", unit="domain", file=sys.stderr, leave=False):
        quick_splits = Splits(*get_generator(spec.family.generator).quick_splits) if quick else None
        domain = build_domain(spec, seed, cache, quick_splits, workers)
        splits = {}
        for split in SPLITS:
            windows = domain.windows(split)
            if windows is not None and quick and len(windows) > QUICK_WINDOWS:
                windows = windows.subset(np.arange(QUICK_WINDOWS))
            splits[split] = windows
        if splits["train"] is None or splits["test"] is None:
            raise InputError(f"domain {domain.name}: no 20-frame window in its train or test split")
        value = spec.value if isinstance(spec.value, int | float) else None
        tasks.append(Task(domain.name, splits["train"], splits["val"], splits["test"], value))
        domains.append(domain)
    return tasks, domains


def make_showcases(curriculum: list[DomainSpec], tasks: list[Task], seed: int) -> tuple[list, dict]:
    """Per task: evenly spaced sample test scenes and a longer rollout cut into windows.

    Returns the showcases and, per task, the rollout's positions and agent ids.
    """
    showcases, rollouts = [], {}
    for spec, task in zip(curriculum, tasks, strict=True):
        count = min(SAMPLE_SCENES, len(task.test))
        scenes = task.test.subset(np.linspace(0, len(task.test) - 1, count).astype(int))
        scene = rollout_scene(spec, seed, ROLLOUT_FRAMES)
        windows = cut_windows(scene) if scene is not None else None
        show = Showcase(task.name, scenes)
        if windows is not None:
            starts, _ = window_members(scene, windows.positions.shape[1])
            show.rollout_windows = windows
            show.rollout_frames = starts + windows.obs_len - 1
            rollouts[task.name] = (scene.positions, scene.agent_ids)
        showcases.append(show)
    return showcases, rollouts


def parse_settings(items: list[str], methods: list[str]) -> dict[str, dict[str, Any]]:
    """``--set SCOPE.KEY=VALUE`` -> {scope: {key: value}}; scope: model, train or a method."""
    settings: dict[str, dict[str, Any]] = {}
    for item in items:
        key, sep, text = item.partition("=")
        scope, dot, name = key.partition(".")
        if not sep or not dot or not name:
            raise InputError(
                f"--set {item!r}: expected SCOPE.KEY=VALUE, e.g. c2inet-online.pruning=false"
            )
        if scope not in ("model", "train", *methods):
            raise InputError(
                f"--set {item!r}: scope {scope!r} is not model, train or a chosen method"
            )
        lowered = text.strip().lower()
        value: Any = {"true": True, "false": False}.get(lowered, text)
        if isinstance(value, str):
            for kind in (int, float):
                try:
                    value = kind(text)
                    break
                except ValueError:
                    pass
        settings.setdefault(scope, {})[name] = value
    return settings


def window_counts(task: Task) -> dict[str, int]:
    """Windows per split of a task (0 for a missing split)."""
    return {s: 0 if getattr(task, s) is None else len(getattr(task, s)) for s in SPLITS}


def write_figures(folder: Path, results: dict[str, dict], labels: list[str]) -> None:
    """The paper's figures of every method: error matrix, per-task ADE, averages over seen tasks."""
    for name, result in results.items():
        figures.error_matrix(name, result["ade"], labels, folder / f"matrix_{name}.png")
        figures.per_task(name, result["ade"], labels, folder / f"per_task_{name}.png")
    figures.average_seen(results, labels, folder / "average_seen.png")


def versions() -> dict[str, str]:
    out = {"python": platform.python_version()}
    for package in ("torch", "numpy", "pymunk", "rerun-sdk", "highway-env", "c2i-testbed"):
        try:
            out[package] = metadata.version(package)
        except metadata.PackageNotFoundError:
            out[package] = "missing"
    return out


def parse_methods(text: str) -> list[str]:
    names = [n.strip() for n in text.split(",") if n.strip()]
    if not names:
        raise InputError("--methods: no method named")
    for name in names:
        try:
            get_method(name)
        except KeyError as error:
            raise InputError(f"--methods: {error.args[0]}") from None
    if len(set(names)) != len(names):
        raise InputError(f"--methods: a method is named twice in {text!r}")
    return names


@guarded
def main(argv: list[str] | None = None) -> int:
    p = parser("sim.run", __doc__.splitlines()[0])
    p.add_argument(
        "--methods", default=DEFAULT_METHODS, help=f"comma-separated (default {DEFAULT_METHODS})"
    )
    p.add_argument("--backbone", choices=sorted(BACKBONES), default="stgat")
    p.add_argument(
        "--epochs",
        type=bounded_int(0, 10_000),
        default=None,
        help="epochs per task (default 20, quick 2)",
    )
    p.add_argument(
        "--seeds",
        type=bounded_int(1, 100),
        default=1,
        help="seeds per method; cells become mean and std",
    )
    p.add_argument(
        "--k",
        type=bounded_int(1, 1000),
        default=None,
        help="samples for best-of-K (default 20, quick 5)",
    )
    p.add_argument("--out", type=Path, default=None, help="output folder (default runs/<scenario>)")
    p.add_argument("--cache", type=Path, default=Path(".cache/domains"), help="domain cache folder")
    p.add_argument("--quick", action="store_true", help="tiny sizes, for smoke tests")
    p.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="SCOPE.KEY=VALUE",
        help="override an option: model.beta_c=0, train.lr=0.001, c2inet-online.pruning=false",
    )
    add_workers(p)
    add_threads(p)
    p.add_argument("--no-record", action="store_true", help="do not write recording.rrd")
    p.add_argument(
        "--rerun",
        default=None,
        metavar="spawn|connect[=URL]",
        help="also stream live to a viewer: spawn one, or connect to one (default URL "
        "rerun+http://127.0.0.1:9876/proxy)",
    )
    args = p.parse_args(argv)
    if (
        args.rerun is not None
        and args.rerun != "spawn"
        and args.rerun.partition("=")[0] != "connect"
    ):
        raise InputError(f"--rerun {args.rerun!r}: expected spawn, connect or connect=URL")
    torch.set_num_threads(args.threads)
    epochs = args.epochs if args.epochs is not None else (2 if args.quick else 20)
    k = args.k if args.k is not None else (5 if args.quick else 20)
    methods = parse_methods(args.methods)
    curriculum = parse_scenario(args.scenario, args.scenarios_dir)
    settings = parse_settings(args.set, methods)
    try:
        model_config = build_options(
            ModelConfig, {"backbone": args.backbone, **settings.get("model", {})}
        )
        train_settings = {**settings.get("train", {}), "epochs": epochs, "k": k, "seed": args.seed}
        train_config = build_options(TrainConfig, train_settings)
        for name in methods:
            get_method(name)(model_config, settings.get(name))
    except ValueError as error:
        raise InputError(f"--set: {error}") from None
    out = args.out or run_folder(args.scenario)
    started = time.perf_counter()
    tasks, domains = make_tasks(curriculum, args.seed, args.quick, args.cache, args.workers)
    one_family = len({s.family.name for s in curriculum}) == 1
    labels = [s.label if one_family else s.name for s in curriculum]

    recorder = None
    if not args.no_record or args.rerun:
        recorder = RunRecorder.create(
            "c2i-testbed",
            f"{args.scenario}-seed{args.seed}",
            None if args.no_record else out / "recording.rrd",
            args.rerun,
            default_blueprint([t.name for t in tasks], SAMPLE_SCENES),
        )
        showcases, rollouts = make_showcases(curriculum, tasks, args.seed)
        for domain in domains:
            recorder.log_domain(domain.name, domain.knobs, domain.stats)
        log_truth(recorder, showcases, rollouts)

    jobs = [(m, s) for m in methods for s in range(args.seeds)]
    runs: dict[str, list] = {m: [] for m in methods}
    drawn: dict[str, dict] = {}
    with tqdm(total=len(jobs) * len(tasks), desc="tasks", unit="task", file=sys.stderr) as bar:
        for name, seed_index in jobs:
            config = replace(train_config, seed=args.seed + seed_index)
            observers = [lambda event, _data: bar.update(1) if event == "task_end" else None]
            if recorder is not None and seed_index == 0:  # the first seed is drawn
                observer = RecordingObserver(recorder, name, showcases, k, seed=args.seed)
                observers.append(observer)
                drawn[name] = observer.final_predictions
            trainer = ContinualTrainer(
                get_method(name)(model_config, settings.get(name)),
                tasks,
                config,
                checkpoint_dir=out / "checkpoints" / name / f"seed_{seed_index}",
                observers=observers,
                progress=lambda it, **kw: tqdm(it, file=sys.stderr, unit="epoch", **kw),
            )
            runs[name].append(trainer.run())
    results: dict[str, dict] = {}
    for name in methods:
        results[name] = summarise(
            [r.matrices for r in runs[name]], [r.summaries for r in runs[name]]
        )
        results[name]["history"] = runs[name][0].history
        results[name]["diagnostics"] = summarise_diagnostics([r.diagnostics for r in runs[name]])
    wall = time.perf_counter() - started

    task_names = [t.name for t in tasks]
    metrics = {
        "scenario": args.scenario,
        "tasks": task_names,
        "labels": labels,
        "k": k,
        "seed": args.seed,
        "epochs": epochs,
        "wall_seconds": round(wall, 1),
        "methods": results,
    }
    write_text_atomic(out / "metrics.json", json.dumps(metrics, indent=1) + "\n")
    for name, result in results.items():
        for key in runs[name][0].matrices:
            write_text_atomic(
                out / "matrices" / f"{name}_{key}.csv", matrix_csv(result[key], task_names)
            )
    run_card = {
        "scenario": args.scenario,
        "seed": args.seed,
        "seeds": args.seeds,
        "methods": methods,
        "quick": args.quick,
        "threads": torch.get_num_threads(),  # what torch uses, not only what was asked
        "model": asdict(model_config),
        "train": asdict(train_config),
        "settings": settings,
        "versions": versions(),
        "domains": [domain_summary(d) for d in domains],
        "windows": {t.name: window_counts(t) for t in tasks},
    }
    write_text_atomic(out / "run_card.json", json.dumps(run_card, indent=1) + "\n")
    report = markdown_report(args.scenario, labels, k, results)
    write_text_atomic(out / "report.md", report)
    write_figures(out / "figures", results, labels)
    if recorder is not None:
        samples = {show.task: show.scenes for show in showcases}
        figures.prediction_grid(samples, drawn, out / "figures" / "predictions.png")
        recorder.log_run_card(
            f"{report}\n## Run card\n\n```json\n{json.dumps(run_card, indent=1)}\n```\n"
        )
        recorder.close()
    print(text_table(results, labels))
    print(f"wall time {wall:.0f} s; wrote {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
