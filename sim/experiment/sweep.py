"""A sweep: the cross product of scenarios, methods, seeds and option values, as one set of jobs.

Every (scenario, setting) is one experiment in its own folder ``<out>/<scenario>/<setting>``
(``sim.run``'s outputs, recording included); all their jobs run together on one backend, and
the sweep is resumable like a run. ``results.parquet`` holds every number in tidy form
(scenario, method, seed, setting, after_task, on_task, metric, value) and ``report.md`` the
final scores, mean and std over seeds. ``--set KEY=V1,V2`` sweeps an option over its values.
"""

from __future__ import annotations

import itertools
import time
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

from c2inet.errors import InputError
from c2inet.files import write_text_atomic
from sim.experiment.backends import run_jobs
from sim.experiment.config import Execution, ExperimentConfig, Job, parse_settings, parse_value
from sim.experiment.curriculum import Curriculum
from sim.experiment.folders import TRUTH_PART, claim, run_root
from sim.experiment.jobs import JobResult, follow, prepare, record_truth, run_job
from sim.experiment.outputs import COLUMNS, tidy_rows, write_outputs, write_results
from sim.progress import progress_bar
from viz.loggers import prepare_tracking


@dataclass(frozen=True)
class SweepConfig:
    """The experiments of a sweep: every scenario with every combination of option values,
    each otherwise configured as ``base`` (its scenario replaced; a variant's settings laid
    over the base's, so a study's ``--set`` reaches every variant)."""

    base: ExperimentConfig
    scenarios: tuple[str, ...]
    grid: dict[str, tuple[Any, ...]] = field(default_factory=dict)  # "SCOPE.KEY" -> values
    variants: tuple[tuple[str, dict[str, dict[str, Any]]], ...] = ()  # named settings instead

    def settings(self) -> list[tuple[str, dict[str, dict[str, Any]]]]:
        """The named variants, or every combination of the grid's values: (label, settings by
        scope)."""
        if self.variants:
            return list(self.variants)
        keys = sorted(self.grid)
        out = []
        for values in itertools.product(*(self.grid[k] for k in keys)):
            items = [f"{k}={v}" for k, v in zip(keys, values, strict=True)]
            out.append((",".join(items) or "default", parse_settings(items)))
        return out

    def experiments(self) -> list[tuple[str, ExperimentConfig]]:
        """(setting label, configuration) of every experiment, scenario by scenario."""
        return [
            (label, replace(self.base, scenario=scenario, settings=layered(self.base, settings)))
            for scenario in self.scenarios
            for label, settings in self.settings()
        ]

    def to_json(self) -> dict[str, Any]:
        return {
            "base": self.base.to_json(),
            "scenarios": list(self.scenarios),
            "grid": {k: list(v) for k, v in self.grid.items()},
            "variants": {label: settings for label, settings in self.variants},
        }


def layered(base: ExperimentConfig, settings: dict[str, dict[str, Any]]) -> dict:
    """``base``'s settings with ``settings`` laid over them, scope by scope."""
    scopes = {**base.settings, **settings}
    return {scope: {**base.settings.get(scope, {}), **settings.get(scope, {})} for scope in scopes}


def parse_grid(items: list[str]) -> dict[str, tuple[Any, ...]]:
    """``SCOPE.KEY=V1,V2`` strings -> {"SCOPE.KEY": (V1, V2)} (values typed as in ``--set``)."""
    grid = {}
    for item in items:
        key, sep, text = item.partition("=")
        if not sep or not text:
            raise InputError(f"--set {item!r}: expected SCOPE.KEY=V1,V2,...")
        parse_settings([f"{key}=0"])  # checks the key's form
        if key in grid:
            raise InputError(f"--set {key}: given twice; list its values once, V1,V2,...")
        values = tuple(parse_value(v) for v in text.split(","))
        if len(set(map(repr, values))) < len(values):
            raise InputError(f"--set {key}: a value is listed twice in {text!r}")
        grid[key] = values
    return grid


def _sweep_job(item: tuple[int, Job], experiments: list[tuple], **options) -> JobResult:
    """Run job ``item[1]`` of experiment ``item[0]`` (its configuration, inputs and folder)."""
    index, job = item
    return run_job(job, *experiments[index], **options)


def combined_report(entries: list[tuple[str, ExperimentConfig, dict]]) -> str:
    """Final scores of every (scenario, setting, method), mean ± std over seeds."""
    lines = [
        "# Sweep",
        "",
        "After the last task: ADE averaged over all tasks (best of K, joint, and K = 1), mean ± "
        "std over seeds; forgetting is the final ADE minus the best earlier one (m).",
        "",
        "| scenario | setting | method | seeds | avg ADE best-of-K | avg ADE K=1 | forgetting |",
        "|---|---|---|---|---|---|---|",
    ]
    marks = set()
    for label, config, metrics in entries:
        for name, m in metrics["methods"].items():
            best, single = (_spread(m, key) for key in ("avg_seen_ade", "avg_seen_ade_k1"))
            forgetting = f"{m['forgetting_final_ade']:+.3f}"
            seeds = str(m["seeds"]) + (" (one: no spread)" if m["seeds"] == 1 else "")
            scenario = config.scenario + (" **quick**" if config.quick else "")
            marks |= {"quick"} if config.quick else set()
            marks |= {"one seed"} if m["seeds"] == 1 else set()
            lines.append(
                f"| {scenario} | {label} | {name} | {seeds} | {best} | {single} | {forgetting} |"
            )
    if marks:
        lines[1:1] = [
            f"**{' and '.join(sorted(marks))}**: rows so marked are a smoke test or a first "
            "look, not a result.",
            "",
        ]
    return "\n".join(lines) + "\n"


def _spread(m: dict[str, Any], key: str) -> str:
    """A final score with its spread over seeds; no spread where one seed gives none."""
    mean = f"{m[key][-1]:.3f}"
    return mean if m["seeds"] == 1 else f"{mean} ± {m[key + '_std'][-1]:.3f}"


def run_sweep(
    sweep: SweepConfig,
    out: Path,
    execution: Execution | None = None,
    resume: bool = False,
    overwrite: bool = False,
    argv: list[str] | None = None,
) -> list[tuple[str, ExperimentConfig, dict]]:
    """Run every experiment of ``sweep`` under ``out``; returns (setting, config, metrics)."""
    execution = replace(execution or Execution(), tracking=out)  # one experiment, side by side
    claim(out, sweep, execution, resume, overwrite)
    prepare_tracking(execution.loggers, out)
    planned = []
    for label, config in sweep.experiments():
        folder = out / run_root(config.scenario).name / run_root(label).name
        planned.append(plan(label, config, folder, execution, resume))
    done = run_together(planned, execution, resume, argv or [])
    entries, rows = [], {c: [] for c in COLUMNS}
    for (label, config, *_), (metrics, results) in zip(planned, done, strict=True):
        entries.append((label, config, metrics))
        for column, values in tidy_rows(label, config, results).items():
            rows[column] += values
    write_results(out / "results.parquet", rows)
    write_text_atomic(out / "report.md", combined_report(entries))
    return entries


Planned = tuple[str, ExperimentConfig, Path, Curriculum]  # label, configuration, folder, inputs


def plan(
    label: str,
    config: ExperimentConfig,
    folder: Path,
    execution: Execution,
    resume: bool,
    curriculum: Curriculum | None = None,
) -> Planned:
    """Claim ``folder`` for one experiment of a set and prepare its data (or take
    ``curriculum``, prepared for an experiment of the same scenario, seed and data). Resuming a
    set that was stopped before it claimed every folder starts the unclaimed ones afresh (a
    folder of ours without ``config.json`` holds no finished work; anything else is refused)."""
    claimed = (folder / "config.json").is_file()
    claim(folder, config, execution, resume and claimed, overwrite=resume and not claimed)
    return label, config, folder, curriculum or prepare(config, execution)


def run_together(
    planned: list[Planned],
    execution: Execution,
    resume: bool,
    argv: list[str],
    costs: list[float] | None = None,
    figures: bool = True,
) -> list[tuple[dict, list[JobResult]]]:
    """Run the jobs of several experiments together on one backend, then write each one's
    outputs in its folder; returns each one's metrics and job results, in order. ``costs``:
    the expected seconds of one job of each experiment, so the longest start first;
    ``figures``: also draw each one's figures (a benchmark's many one-seed runs do not)."""
    started = time.perf_counter()
    items = [(i, job) for i, (_, config, _, _) in enumerate(planned) for job in config.jobs()]
    shared = [(config, curriculum.inputs, folder) for _, config, folder, curriculum in planned]
    tasks = [len(curriculum.inputs.tasks) for *_, curriculum in planned]
    with progress_bar(total=sum(tasks[i] for i, _ in items), desc="tasks") as bar:
        results = run_jobs(
            _sweep_job,
            items,
            (shared,),
            execution.backend,
            execution.jobs,
            execution.ray_address,
            execution.job_options(resume),
            follow(bar),
            lambda item: tasks[item[0]],
            lambda item: costs[item[0]] if costs else 0.0,
        )
    wall = time.perf_counter() - started
    done = []
    for i, (label, config, folder, curriculum) in enumerate(planned):
        mine = [r for (index, _), r in zip(items, results, strict=True) if index == i]
        path = folder / TRUTH_PART
        truth = record_truth(config, curriculum, path, None) if config.record else None
        metrics = write_outputs(
            folder, config, execution, curriculum, mine, truth, wall, argv, label, figures
        )
        done.append((metrics, mine))
    return done
