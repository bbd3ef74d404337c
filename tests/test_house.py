"""The house rules of DESIGN.md, checked: imports point one way (``sim`` -> ``viz`` -> ``c2inet``)
and the learner, with its tests, loads and trains without the simulators or the recorder."""

import ast
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).parents[1]
FORBIDDEN = {
    "c2inet": {"sim", "viz", "pymunk", "highway_env", "gymnasium", "rerun", "matplotlib", "ray"},
    "viz": {"sim", "pymunk", "highway_env", "gymnasium", "ray"},
}


def imported(path: Path) -> set[str]:
    """Top-level names of every module ``path`` imports, wherever in the file."""
    names = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            names |= {alias.name.split(".")[0] for alias in node.names}
        elif isinstance(node, ast.ImportFrom) and node.module and not node.level:
            names.add(node.module.split(".")[0])
    return names


@pytest.mark.parametrize("package", sorted(FORBIDDEN))
def test_imports_point_one_way(package):
    for path in sorted((ROOT / package).rglob("*.py")):
        wrong = imported(path) & FORBIDDEN[package]
        assert not wrong, f"{path.relative_to(ROOT)} imports {sorted(wrong)}"


BLOCKER = """
import sys

BLOCKED = {"sim", "viz", "pymunk", "highway_env", "gymnasium", "rerun"}


class Blocker:
    def find_spec(self, name, path=None, target=None):
        if name.split(".")[0] in BLOCKED:
            raise ImportError(f"{name} is blocked: the learner must not need it")


sys.meta_path.insert(0, Blocker())
"""


def test_the_learner_and_its_tests_load_and_train_without_the_simulators(tmp_path):
    """Every learner test module imports with the simulators and the recorder blocked (their
    collection), and a continual run trains there (the determinism test). The static check
    above covers imports inside functions, so the learner's suite need not run twice."""
    (tmp_path / "block_simulators.py").write_text(BLOCKER)
    for args in (
        ["--collect-only", "tests/c2inet"],
        ["tests/c2inet/test_learner.py::test_same_seed_same_training_on_cpu"],
    ):
        done = subprocess.run(
            [sys.executable, "-m", "pytest", "-q", "-x", "-p", "block_simulators", *args],
            cwd=ROOT,
            env={"PYTHONPATH": str(tmp_path), "PATH": "/usr/bin:/bin"},
            capture_output=True,
            text=True,
            check=False,
        )
        assert done.returncode == 0, done.stdout[-3000:]
        summary = done.stdout.strip().splitlines()[-1]
        assert re.search(r"\d+ (passed|tests collected)", summary), summary
        assert "error" not in summary, summary
