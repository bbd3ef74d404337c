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


def readme_snippet() -> str:
    text = (Path(__file__).parents[1] / "README.md").read_text()
    return text.split("## From Python", 1)[1].split("```python\n", 1)[1].split("```", 1)[0]


def test_the_readmes_snippet_runs_as_pasted_and_leaves_one_run_folder(tmp_path):
    """Issue 65: pasted into a file and run, the snippet ends and leaves exactly one run folder;
    without its guard, two jobs are one clear line before any folder or worker."""
    (tmp_path / "snippet.py").write_text(readme_snippet())
    done = subprocess.run(
        [sys.executable, "snippet.py"], cwd=tmp_path, capture_output=True, text=True, timeout=600
    )
    assert done.returncode == 0, done.stderr[-3000:]
    runs = [p for p in (tmp_path / "runs" / "crowd_noise_0.1..0.3").iterdir() if p.name != "latest"]
    assert len(runs) == 1 and (runs[0] / "metrics.json").is_file()
    unguarded = "\n".join(
        line.removeprefix("    ")
        for line in readme_snippet().splitlines()
        if "__main__" not in line
    )
    (tmp_path / "other").mkdir()
    (tmp_path / "other" / "unguarded.py").write_text(unguarded)
    done = subprocess.run(
        [sys.executable, "unguarded.py"], cwd=tmp_path / "other", capture_output=True, text=True
    )
    assert done.returncode != 0 and 'if __name__ == "__main__":' in done.stderr
    assert not (tmp_path / "other" / "runs").exists()
