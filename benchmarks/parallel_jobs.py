"""How much faster are 2 jobs at once than 1, on runs of the default size?

Runs ``sim.run`` on ``crowd_noise_0.1..0.6`` at the default sizes (20 epochs, K = 20, recording
on) with ``--jobs 1`` and ``--jobs 2`` on the local backend, one torch thread per job, the
domains already in the cache; each layout twice, interleaved, best time kept. Two layouts: the
default methods (whose jobs differ in size: C2INet's is the longest, constant velocity's almost
free) and two seeds of C2INet and fine-tune (four jobs that pair evenly). Prints the wall times
side by side and the speed-ups, and checks that the metrics are identical.

    python benchmarks/parallel_jobs.py [--rounds 2] [--quick]
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
import time
from pathlib import Path

SCENARIO = "crowd_noise_0.1..0.6"
LAYOUTS = {
    "default methods (3 jobs)": ["--methods", "c2inet-online,finetune,cv"],
    "c2inet + finetune, 2 seeds (4 jobs)": ["--methods", "c2inet-online,finetune", "--seeds", "2"],
}


def timed_run(args: list[str], jobs: int, out: Path, cache: Path) -> float:
    command = [sys.executable, "-m", "sim.run", "--scenario", SCENARIO, *args]
    command += ["--jobs", str(jobs), "--threads", "1", "--cache", str(cache), "--out", str(out)]
    start = time.perf_counter()
    subprocess.run(command, check=True, capture_output=True)
    return time.perf_counter() - start


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--rounds", type=int, default=2)
    p.add_argument("--quick", action="store_true", help="quick sizes (checks the script only)")
    args = p.parse_args()
    extra = ["--quick"] if args.quick else []
    with tempfile.TemporaryDirectory() as tmp:
        root, cache = Path(tmp), Path(".cache/domains")
        warm = [sys.executable, "-m", "sim.run", "--scenario", SCENARIO, "--methods", "cv"]
        subprocess.run(
            [*warm, *extra, "--cache", str(cache), "--out", str(root / "warm"), "--no-record"],
            check=True,
            capture_output=True,
        )
        best: dict[tuple[str, int], float] = {}
        for round_ in range(args.rounds):
            for name, layout in LAYOUTS.items():
                for jobs in (1, 2):
                    out = root / f"{round_}-{jobs}-{len(layout)}"
                    seconds = timed_run([*layout, *extra], jobs, out, cache)
                    best[name, jobs] = min(best.get((name, jobs), seconds), seconds)
                    metrics = (out / "metrics.json").read_bytes()
                    first = root / f"0-1-{len(layout)}" / "metrics.json"
                    assert metrics == first.read_bytes(), "metrics differ between --jobs"
    print(f"{'layout':40s} {'--jobs 1':>10s} {'--jobs 2':>10s} {'speed-up':>9s}")
    for name in LAYOUTS:
        one, two = best[name, 1], best[name, 2]
        print(f"{name:40s} {one:9.1f}s {two:9.1f}s {one / two:8.2f}x")
    print("metrics.json identical for --jobs 1 and 2 in every round")


if __name__ == "__main__":
    from viz.cli import run_script

    raise SystemExit(run_script(main))
