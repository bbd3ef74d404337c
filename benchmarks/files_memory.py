"""Peak memory and CPU time of reading a recorded trajectory file (the files generator).

Writes a synthetic ETH-UCY-format file (groups of 20 agents over 40 frames, as many groups as
``--mb`` asks), then reads it in a fresh process and prints its size, rows, peak resident memory
above the interpreter's own and the ratio to the file's size (``FilesGenerator.memory_bytes``
budgets six times the size).

    python benchmarks/files_memory.py [--mb 40]
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

READ = """
import resource, sys, time
from pathlib import Path
from sim.generators.files import read_trajectory_file
base = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
start = time.process_time()
scenes = read_trajectory_file(Path(sys.argv[1]))
peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
print(len(scenes), time.process_time() - start, (peak - base) / 1024)
"""


def write_file(path: Path, megabytes: float) -> int:
    """Groups of 20 agents walking 40 frames, until the file has about ``megabytes``."""
    rng = np.random.default_rng(0)
    rows, group = 0, 0
    with path.open("w") as file:
        while file.tell() < megabytes * 1e6:
            for a in range(20):
                start, (x, y) = group * 100 + rng.integers(0, 10), rng.normal(size=2) * 5
                file.writelines(
                    f"{(start + t) * 10}\t{group * 20 + a}\t{x + 0.1 * t:.3f}\t{y:.3f}\n"
                    for t in range(40)
                )
                rows += 40
            group += 1
    return rows


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--mb", type=float, default=40.0, help="size of the synthetic file")
    args = p.parse_args()
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "recording.txt"
        rows = write_file(path, args.mb)
        size = path.stat().st_size / 1e6
        out = subprocess.run(
            [sys.executable, "-c", READ, str(path)], capture_output=True, text=True
        )
        scenes, cpu, peak = out.stdout.split()
    print(f"{'file MB':>8} {'rows':>10} {'scenes':>7} {'CPU s':>6} {'peak MB':>8} {'peak/size':>9}")
    ratio = float(peak) / size
    print(f"{size:8.1f} {rows:10,d} {scenes:>7} {float(cpu):6.2f} {float(peak):8.0f} {ratio:9.1f}")


if __name__ == "__main__":
    from viz.cli import run_script

    raise SystemExit(run_script(main))
