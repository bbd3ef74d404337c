"""The experiment engine: configuration, jobs, backends, outputs, sweeps.

It sits above the world (``sim``'s scenario language, families, generators and data model) and
below the commands and studies, which only call it.

From a notebook::

    from sim.experiment import ExperimentConfig, run_experiment
    metrics = run_experiment(ExperimentConfig("crowd_noise_0.1..0.3", quick=True))
"""

from sim.experiment.config import (
    DEFAULT_METHODS,
    Execution,
    ExperimentConfig,
    Job,
    parse_settings,
)
from sim.experiment.runner import run_experiment

__all__ = [
    "DEFAULT_METHODS",
    "Execution",
    "ExperimentConfig",
    "Job",
    "parse_settings",
    "run_experiment",
]
