"""Compile the numba kernels once, before a parallel test run on a fresh clone.

numba compiles the crowd controllers and the learner's kernels on first use and keeps them
beside the package (``c2inet/jit.py``); on a fresh clone every test process that starts before
they are kept compiles them again (14 CPU s each). One small run keeps them first; CI runs it
beside the linters.

    python scripts/warm_kernels.py
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from sim import Execution, ExperimentConfig, run_experiment  # noqa: E402


def main() -> int:
    config = ExperimentConfig(
        "crowd_noise_0.1", methods=("finetune",), quick=True, epochs=1, record=False
    )
    with tempfile.TemporaryDirectory() as folder:
        root = Path(folder)
        run_experiment(config, root / "run", Execution(cache=root / "cache", workers=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
