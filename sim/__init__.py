"""The world and the application: scenario language, generators, data model, entry points.

From Python: ``learner_tasks("crowd_noise_0.1..0.3")`` turns a scenario into the learner's
tasks; ``run_experiment(ExperimentConfig(...))`` runs and writes a whole experiment.
"""

__all__ = ["Execution", "ExperimentConfig", "learner_tasks", "run_experiment"]


def __getattr__(name: str):
    """The names above, imported on first use: ``python -m sim.generate`` and friends must not
    find their own module already imported by the package."""
    if name in __all__:
        from sim import experiment
        from sim.experiment import curriculum

        return getattr(curriculum if name == "learner_tasks" else experiment, name)
    raise AttributeError(f"module 'sim' has no attribute {name!r}")
