"""Fuzzing every input path at scale: counts of each outcome per target, side by side.

Runs ``--cases`` generated inputs (default 10,000, spread over the targets of
``tests/sim/fuzzing.py``: scenario, --set, sim.run, sim.generate, ETH-UCY, SDD and TrajNet++
files, family files, config files, tuning storages, damaged run folders; a target that costs a
run a case, such as a run folder resumed, gets its share scaled as CI scales it) and prints, per
target, how many gave a result (``ok``), the project's one-line error (``input error``),
another exception (``crash``) or no answer in time (``hang``), with the first input of each bad
kind.

    python benchmarks/fuzz.py [--cases 10000] [--target "run folder"]

The inputs are the same on every run (Hypothesis derandomised).
"""

from __future__ import annotations

import argparse
import collections
import sys
import time
from pathlib import Path

from hypothesis import HealthCheck, given, settings

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "sim"))  # test machinery

from fuzzing import TARGETS, Hang, outcome  # noqa: E402

KINDS = ("ok", "input error", "crash", "hang")
CI_EXAMPLES = 150  # what CI draws of a target that costs little a case


def fuzz(target, cases: int) -> tuple[collections.Counter, dict[str, str]]:
    counts: collections.Counter = collections.Counter()
    first: dict[str, str] = {}

    @settings(
        max_examples=cases,
        deadline=None,
        database=None,
        suppress_health_check=list(HealthCheck),
        derandomize=True,
    )
    @given(target.strategy)
    def run(case):
        try:
            kind = outcome(target, case)
        except Hang:
            kind = "hang"
        except Exception as error:  # counted, not raised: the run goes on
            kind = "crash"
            first.setdefault(kind, f"{type(error).__name__}: {error!s:.120} for {case!r:.200}")
        counts[kind] += 1

    run()
    return counts, first


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--cases", type=int, default=10_000)
    p.add_argument("--target", action="append", help="only these targets (repeatable)")
    args = p.parse_args()
    targets = [t for t in TARGETS if not args.target or t.name in args.target]
    if not targets:
        p.error(f"--target: none of {args.target}; known: {', '.join(t.name for t in TARGETS)}")
    per_target = -(-args.cases // len(targets))
    print(f"{'target':<14}" + "".join(f"{k:>13}" for k in KINDS) + f"{'s':>8}")
    total: collections.Counter = collections.Counter()
    for target in targets:
        start = time.perf_counter()
        counts, first = fuzz(target, max(1, per_target * target.examples // CI_EXAMPLES))
        total += counts
        row = "".join(f"{counts[k]:>13}" for k in KINDS)
        print(f"{target.name:<14}{row}{time.perf_counter() - start:>8.1f}", flush=True)
        for kind, example in first.items():
            print(f"    first {kind}: {example}")
    print(f"{'all':<14}" + "".join(f"{total[k]:>13}" for k in KINDS))


if __name__ == "__main__":
    from viz.cli import run_script

    raise SystemExit(run_script(main))
