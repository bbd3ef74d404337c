"""The experiment as a function: :func:`run_experiment` generates the curriculum, runs every
job on the chosen backend and writes every output (``sim.experiment.outputs``).

From a notebook:

    from sim.experiment import ExperimentConfig, run_experiment
    metrics = run_experiment(ExperimentConfig("crowd_noise_0.1..0.3", quick=True))
"""

from __future__ import annotations

import sys
import time
from pathlib import Path
from typing import Any

import torch

from sim.experiment.backends import check_guarded_main, run_jobs
from sim.experiment.config import Execution, ExperimentConfig
from sim.experiment.estimate import describe, job_seconds, run_seconds
from sim.experiment.folders import TRUTH_PART, claim, output_folder
from sim.experiment.jobs import follow, prepare, record_truth, run_job
from sim.experiment.outputs import write_outputs
from sim.progress import progress_bar
from viz.live import check_reachable, viewer_url
from viz.loggers import prepare_tracking


def run_experiment(
    config: ExperimentConfig,
    out: Path | None = None,
    execution: Execution | None = None,
    resume: bool = False,
    overwrite: bool = False,
    argv: list[str] | None = None,
) -> dict[str, Any]:
    """Generate the curriculum, run every job on the chosen backend, write every output.

    ``out``: the run's folder (default: a fresh ``runs/<scenario>/<timestamp>``, see
    ``sim.experiment.folders.output_folder``); a folder holding anything else is refused unless
    ``overwrite``. With ``resume``, finished jobs are read back and unfinished ones continue from
    their last task; the configuration must equal the folder's. Returns ``metrics.json``.
    """
    execution = execution or Execution()
    if execution.backend == "local":
        check_guarded_main(execution.jobs)
    if execution.rerun not in (None, "spawn"):
        check_reachable(viewer_url(execution.rerun))
    out = output_folder(config.scenario, out, resume)
    claim(out, config, execution, resume, overwrite)
    prepare_tracking(execution.loggers, execution.tracking or out)
    torch.set_num_threads(execution.threads)
    started = time.perf_counter()
    curriculum = prepare(config, execution)
    truth = None
    if config.record or execution.rerun:
        path = out / TRUTH_PART if config.record else None
        truth = record_truth(config, curriculum, path, execution.rerun)
    jobs = config.jobs()
    tasks = len(curriculum.inputs.tasks)
    each: dict[str, float] = {}  # a job's estimated seconds by method: the longest go first
    if not resume and not config.quick:  # timing a quick run would cost as much as running it
        each = job_seconds(config, curriculum.inputs.tasks)
        estimate = run_seconds(config, each, execution.jobs)
        prepared = time.perf_counter() - started  # the domains, generated or read
        size = "" if config.size == "full" else f"{config.size}: "
        print(
            f"{size}{len(jobs)} jobs x {tasks} tasks, {execution.jobs} at a time: about "
            f"{describe(prepared + estimate)} in all ({describe(prepared)} of it preparing the "
            f"domains, done; about {describe(estimate)} of training and evaluation, timed on "
            "this machine)",
            file=sys.stderr,
        )
    with progress_bar(total=len(jobs) * tasks, desc="tasks", unit="task") as bar:
        results = run_jobs(
            run_job,
            jobs,
            shared=(config, curriculum.inputs, out),
            backend=execution.backend,
            processes=execution.jobs,
            ray_address=execution.ray_address,
            options=execution.job_options(resume),
            progress=follow(bar),
            tasks_of=lambda _job: tasks,
            cost_of=lambda job: each.get(job.method, 0.0),
        )
    wall = time.perf_counter() - started
    return write_outputs(out, config, execution, curriculum, results, truth, wall, argv or sys.argv)
