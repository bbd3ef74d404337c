"""A curriculum as the learner and the recording take it: tasks of windows, and showcases.

``learner_tasks("crowd_noise_0.1..0.3")`` is the one call from a scenario to the learner's
tasks; ``make_showcases`` picks what the recording draws of each task.
"""

from __future__ import annotations

import math
import os
import sys
import time
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from c2inet.data import OBS_LEN, PRED_LEN, Windows
from c2inet.errors import InputError
from c2inet.trainer import Task
from sim.data import SPLITS, cut_windows, window_members
from sim.domains import build_domain, cache_path, rollout_scene
from sim.experiment.config import Execution, ExperimentConfig
from sim.families import Splits, Windowing
from sim.generators import Generator, get_generator
from sim.scenario import DomainSpec, parse_scenario
from viz.observer import Showcase

QUICK_WINDOWS = 24  # at most this many windows per split in --quick runs (real data)
SAMPLE_SCENES = 5  # test scenes per task drawn in the recording (with the rollout, a 3 x 2 grid)
ROLLOUT_FRAMES = 50  # frames of the longer episode played per domain (20 s at 0.4 s)


@dataclass
class JobInputs:
    """What every job of an experiment reads: the learner's tasks and what the recording draws."""

    tasks: list[Task]
    showcases: list[Showcase]


@dataclass
class Curriculum:
    """The generated domains of an experiment, as the learner and the recording use them."""

    specs: list[DomainSpec]
    domains: list
    inputs: JobInputs
    rollouts: dict[str, tuple]
    labels: list[str]


def experiment_tasks(
    specs: list[DomainSpec], config: ExperimentConfig, execution: Execution
) -> tuple[list[Task], list]:
    """:func:`make_tasks` with the seed and sizes of ``config`` and where and how
    ``execution`` generates (cache, workers, memory budget)."""
    return make_tasks(
        specs,
        config.seed,
        config.quick,
        execution.cache,
        execution.workers,
        execution.memory_budget,
    )


def _splits(spec: DomainSpec, quick: bool) -> Splits | None:
    """The scene counts a domain is made with: its generator's tiny ones when quick, else its
    family's (None)."""
    return Splits(*get_generator(spec.family.generator).quick_splits) if quick else None


def is_cached(config: ExperimentConfig, execution: Execution) -> bool:
    """Whether every domain of ``config`` is in ``execution``'s cache: preparing it generates
    nothing."""
    return all(
        cache_path(spec, config.seed, execution.cache, _splits(spec, config.quick)).is_file()
        for spec in config.specs
    )


def make_tasks(
    specs: list[DomainSpec],
    seed: int,
    quick: bool,
    cache: Path,
    workers: int,
    memory_budget: float | None = None,
) -> tuple[list[Task], list]:
    """Domains of the curriculum as learner tasks (windows per split)."""
    tasks, domains = [], []
    for i, spec in enumerate(specs, 1):
        counts = _splits(spec, quick)  # the scenes a split, where quick sets them
        cached = cache is not None and cache_path(spec, seed, cache, counts).is_file()
        started = time.perf_counter()
        domain = build_domain(spec, seed, cache, counts, workers, memory_budget)
        how = "read from the cache" if cached else f"made in {time.perf_counter() - started:.1f} s"
        sizes = "/".join(str(len(domain.scenes[split])) for split in SPLITS)
        print(f"domain {i}/{len(specs)} {domain.name}: {how} ({sizes} scenes)", file=sys.stderr)
        contact = get_generator(spec.family.generator).contact(spec.knobs)
        splits = {
            split: None if w is None else replace(w, contact=contact)
            for split, w in domain_windows(domain, spec.family.windowing).items()
        }
        if quick:
            splits = {k: _first(w, QUICK_WINDOWS) for k, w in splits.items()}
        if splits["train"] is None or splits["test"] is None:
            raise InputError(f"domain {domain.name}: no 20-frame window in its train or test split")
        value = spec.value if isinstance(spec.value, int | float) else None
        tasks.append(Task(domain.name, splits["train"], splits["val"], splits["test"], value))
        domains.append(domain)
    return tasks, domains


def domain_windows(domain, windowing: Windowing) -> dict[str, Windows | None]:
    """A domain's windows per split as its family's ``[windows]`` table says: training windows
    every ``stride`` frames, their first ``share``; every split without windows of fewer than
    ``min_agents`` agents; and, where the domain has no validation split and ``val_share`` > 0,
    the training windows' last ``val_share`` held out as one, a window every ``val_stride``
    frames (the windows that share frames with it dropped from training, so that no validation
    frame is trained on)."""
    keep = windowing.min_agents
    splits = {split: domain.windows(split, 1, 1.0, keep) for split in ("val", "test")}
    every = domain.windows("train", 1, 1.0, keep)
    if splits["val"] is None and windowing.val_share > 0 and every is not None:
        cut = len(every) - math.ceil(windowing.val_share * len(every))
        splits["val"] = every.subset(np.arange(cut, len(every), windowing.val_stride))
        gap = max(cut - (OBS_LEN + PRED_LEN - 1), 0)  # a window shares frames with the 19 before
        train = every.subset(np.arange(0, gap, windowing.stride))
        if windowing.share < 1:
            train = train.subset(np.arange(math.ceil(windowing.share * len(train))))
    else:
        train = domain.windows("train", windowing.stride, windowing.share, keep)
    return {"train": train, **splits}


def _first(windows: Windows | None, count: int) -> Windows | None:
    """At most the first ``count`` of ``windows``."""
    if windows is None or len(windows) <= count:
        return windows
    return windows.subset(np.arange(count))


def make_showcases(specs: list[DomainSpec], tasks: list[Task], seed: int) -> tuple[list, dict]:
    """Per task: evenly spaced sample test scenes and a longer rollout cut into windows.

    Returns the showcases and, per task, the rollout's positions and agent ids.
    """
    showcases, rollouts = [], {}
    for spec, task in zip(specs, tasks, strict=True):
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


def learner_tasks(
    scenario: str,
    seed: int = 0,
    quick: bool = False,
    data: dict[str, Any] | None = None,
    cache: Path | None = Path(".cache/domains"),
    scenarios_dir: tuple[Path, ...] = (),
) -> list[Task]:
    """The learner's tasks of a scenario, one per domain, generated or read from ``cache``.

    ``data`` overrides knobs or split sizes, as ``--set data.KEY=VALUE`` does.
    """
    specs = parse_scenario(scenario, list(scenarios_dir), data)
    return make_tasks(specs, seed, quick, cache, os.cpu_count() or 1)[0]


def knob_grid(specs: list[DomainSpec], where: str, example: str, single_scenes: bool = False):
    """``specs`` if they are two values or more of one numeric family, else an
    :class:`InputError` naming ``where``; with ``single_scenes``, the family's generator must
    also simulate a scene on its own (:func:`scene_windows`)."""
    family = specs[0].family
    if len(specs) < 2 or len({s.family.name for s in specs}) != 1 or family.values:
        raise InputError(f"{where}: give one numeric family, two values or more, e.g. {example}")
    if single_scenes and get_generator(family.generator).rollout is Generator.rollout:
        raise InputError(f"{where}: family {family.name!r} cannot simulate single scenes")
    return specs


def scene_windows(family, values, seeds: list[np.random.SeedSequence]) -> Windows:
    """One scene of ``family`` per (knob value, seed), each simulated on its own (the
    generator's ``rollout``), as learner windows: the scenes of a drift or an active round."""
    generator = get_generator(family.generator)()
    parts = [
        cut_windows(generator.rollout(family.knobs_for(float(v)), seed, OBS_LEN + PRED_LEN))
        for v, seed in zip(values, seeds, strict=True)
    ]
    return Windows.concat([p for p in parts if p is not None])
