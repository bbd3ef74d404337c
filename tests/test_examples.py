"""The examples run as a user runs them, from a folder of their own."""

import subprocess
import sys
from pathlib import Path

import pytest

EXAMPLES = Path(__file__).parents[1] / "examples"


@pytest.mark.parametrize("script", sorted(p.name for p in EXAMPLES.glob("*.py")))
def test_every_example_runs(tmp_path, script):
    done = subprocess.run(
        [sys.executable, str(EXAMPLES / script)],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        check=False,
    )
    assert done.returncode == 0, done.stderr[-3000:]
    assert done.stdout.strip(), "an example says what it found"


def test_the_packages_re_export_what_a_notebook_needs():
    import c2inet
    import sim

    assert set(c2inet.__all__) >= {"Windows", "Task", "ContinualTrainer", "TrainConfig"}
    assert {"ModelConfig", "get_method", "summarise"} <= set(c2inet.__all__)
    assert all(callable(getattr(c2inet, name)) for name in c2inet.__all__)
    assert {"learner_tasks", "run_experiment", "ExperimentConfig"} <= set(sim.__all__)
