"""The world and the application: scenario language, generators, data model, entry points.

From Python: ``learner_tasks("crowd_noise_0.1..0.3")`` turns a scenario into the learner's
tasks; ``run_experiment(ExperimentConfig(...))`` runs and writes a whole experiment.

The simulators and the recorder are the ``sim`` extra of the learner (``pip install
'c2i-testbed[sim]'``; ``make`` installs it): without them the learner (``c2inet``) works, and a
command says in one line what to install.
"""

import importlib.util
import sys
from pathlib import Path

__all__ = ["Execution", "ExperimentConfig", "learner_tasks", "run_experiment"]
# the modules of the `sim` extra (pyproject.toml) that the world and the recorder import
SIM_EXTRA = ("pymunk", "highway_env", "gymnasium", "numba", "rerun", "matplotlib", "pyarrow")


def _missing() -> list[str]:
    def absent(name: str) -> bool:
        try:
            return importlib.util.find_spec(name) is None
        except (ImportError, ValueError):  # a broken install, or a module blocked as None
            return True

    return [name for name in SIM_EXTRA if absent(name)]


if _lacking := _missing():
    _message = (
        f"the simulators and the recorder are not installed (no {', '.join(_lacking)}): "
        "pip install 'c2i-testbed[sim]'"
    )
    if sys.argv and (sys.argv[0] == "-m" or Path(sys.argv[0]).name.startswith("c2i-")):
        print(f"error: {_message}", file=sys.stderr)  # a command: one line, exit code 2
        raise SystemExit(2)
    raise ImportError(_message)


def __getattr__(name: str):
    """The names above, imported on first use: ``python -m sim.generate`` and friends must not
    find their own module already imported by the package."""
    if name in __all__:
        from sim import experiment
        from sim.experiment import curriculum

        return getattr(curriculum if name == "learner_tasks" else experiment, name)
    raise AttributeError(f"module 'sim' has no attribute {name!r}")
