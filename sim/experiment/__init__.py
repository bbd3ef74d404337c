"""The experiment engine: configuration, jobs, backends, outputs, sweeps.

It sits above the world (``sim``'s scenario language, families, generators and data model) and
below the commands and studies, which only call it.

From a notebook:

    from sim.experiment import ExperimentConfig, run_experiment
    metrics = run_experiment(ExperimentConfig("crowd_noise_0.1..0.3", quick=True))
"""

from c2inet.lazy import lazy_exports

_HOMES = {
    "DEFAULT_METHODS": "sim.experiment.config",
    "Execution": "sim.experiment.config",
    "ExperimentConfig": "sim.experiment.config",
    "Job": "sim.experiment.config",
    "parse_settings": "sim.experiment.config",
    "run_experiment": "sim.experiment.runner",
}
__all__ = sorted(_HOMES)

# imported on first use: a process that needs one engine module (a backend's worker,
# ``sim.experiment.backends`` in a user's script) does not import them all
__getattr__ = lazy_exports(__name__, _HOMES)
