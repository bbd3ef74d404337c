"""How much faster is the fair benchmark with 2 jobs at once than with 1, and where does its
time go?

Runs ``sim.bench`` on a reduced preset (``crowd_noise_0.1..0.3`` at the default sizes but
``--epochs 2``; fine-tune, EWC, DER++ and C2INet-online; 3 tuning trials and 3 seeds a method,
so 24 jobs) with ``--jobs 1`` and ``--jobs 2``, interleaved, the domains already in the cache,
one torch thread per job. Prints the wall times side by side, the speed-up, the CPU seconds of
the tuning and the evaluation jobs (from their ``result.json``) under each, the speed-up those
allow (two jobs at once slow each other down: the CPU seconds grow), and checks that the two
leaderboards are identical.

    python benchmarks/bench_parallel.py [--rounds 1] [--epochs 2] [--trials 3] [--jobs 1,2]

``--trials 6`` (the presets' budget) lets a method's 3 start-up trials share a round; ``--jobs 2``
alone times one side, e.g. of another checkout, to compare two versions.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

SCENARIO = "crowd_noise_0.1..0.3"
METHODS = "finetune,ewc,derpp,c2inet-online"


def timed_bench(jobs: int, epochs: int, trials: int, out: Path, cache: Path) -> float:
    command = [sys.executable, "-m", "sim.bench", "--scenario", SCENARIO, "--methods", METHODS]
    command += ["--trials", str(trials), "--seeds", "3", "--epochs", str(epochs), "--no-record"]
    command += ["--jobs", str(jobs), "--cache", str(cache), "--out", str(out)]
    start = time.perf_counter()
    subprocess.run(command, check=True, capture_output=True)
    return time.perf_counter() - start


def cpu_seconds(folder: Path) -> float:
    return sum(
        json.loads(p.read_text()).get("cpu_seconds") or 0.0 for p in folder.rglob("result.json")
    )


def ranking(out: Path) -> list[dict]:
    """The leaderboard's entries but their CPU seconds (which vary from run to run)."""
    entries = json.loads((out / "leaderboard.json").read_text())["entries"]
    return [{k: v for k, v in e.items() if k != "cpu_seconds"} for e in entries]


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--rounds", type=int, default=1)
    p.add_argument("--epochs", type=int, default=2)
    p.add_argument("--trials", type=int, default=3)
    p.add_argument("--jobs", default="1,2", help="the --jobs values timed, in turn")
    args = p.parse_args()
    sides = [int(j) for j in args.jobs.split(",")]
    with tempfile.TemporaryDirectory() as tmp:
        root, cache = Path(tmp), Path(".cache/domains")
        subprocess.run(  # the domains into the cache
            [
                sys.executable,
                "-m",
                "sim.run",
                "--scenario",
                SCENARIO,
                "--methods",
                "cv",
                "--no-record",
                "--cache",
                str(cache),
                "--out",
                str(root / "warm-run"),
            ],
            check=True,
            capture_output=True,
        )
        best: dict[int, float] = {}
        for round_ in range(args.rounds):
            for jobs in sides:
                out = root / f"{round_}-{jobs}"
                seconds = timed_bench(jobs, args.epochs, args.trials, out, cache)
                best[jobs] = min(best.get(jobs, seconds), seconds)
                assert ranking(out) == ranking(root / f"0-{sides[0]}"), "the leaderboards differ"
        cpu = {jobs: cpu_seconds(root / f"0-{jobs}") for jobs in sides}
        first = root / f"0-{sides[0]}"
        tuning, evaluation = (cpu_seconds(first / part) for part in ("tuning", "evaluation"))
    jobs_run = 4 * (args.trials + 3)
    if sides != [1, 2]:
        for jobs in sides:
            print(f"reduced benchmark ({jobs_run} jobs), --jobs {jobs}: {best[jobs]:.1f} s wall,")
            print(f"  job CPU {cpu[jobs]:.1f} s")
        return
    serial = best[1] - cpu[1]  # start-up, data and outputs: the same for both
    name = f"reduced benchmark ({jobs_run} jobs)"
    print(f"{name:32s} {'--jobs 1':>10s} {'--jobs 2':>10s} {'speed-up':>9s}")
    print(f"{'wall':32s} {best[1]:9.1f}s {best[2]:9.1f}s {best[1] / best[2]:8.2f}x")
    print(f"{'job CPU':32s} {cpu[1]:9.1f}s {cpu[2]:9.1f}s {cpu[2] / cpu[1]:8.2f}x")
    print(
        f"--jobs 1: tuning {tuning:.0f} s and evaluation {evaluation:.0f} s of job CPU, "
        f"{serial:.0f} s of start-up, data and outputs. With two jobs at once each costs "
        f"{cpu[2] / cpu[1]:.2f}x the CPU: at best {best[1] / (serial + cpu[2] / 2):.2f}x "
        "with --jobs 2, perfectly packed"
    )
    print("leaderboard.json identical for --jobs 1 and 2 (but the CPU seconds)")


if __name__ == "__main__":
    from viz.cli import run_script

    raise SystemExit(run_script(main))
