"""Two runs of the same methods and seeds that differ only in the backbone (``--backbone
stgat-cell`` against ``stgat``: the network in tensor operations or compiled), side by side:
each method's final average ADE (the last row of the task-by-task matrix, best of K) per seed,
over the methods and seeds both runs hold, the mean over seeds, their spread, the difference
with its paired 95 % interval, and each run's training CPU seconds. The compiled backbone
changes rounding only; this shows what that does after training.

    python -m sim.run --scenario crowd_noise_0.1..0.6 --methods finetune,c2inet-online,derpp \\
        --seeds 3 --set data.splits.train=100 --no-record --backbone stgat-cell --out A
    (the same with --backbone stgat --out B)
    python benchmarks/decoder_numerics.py A B
"""

from __future__ import annotations

import argparse
import json
import statistics
from pathlib import Path


def finals(run: Path) -> dict[str, dict[int, tuple[float, float]]]:
    """Per method and seed: the final average ADE and the job's CPU seconds."""
    out: dict[str, dict[int, tuple[float, float]]] = {}
    for result in sorted(run.glob("jobs/*/seed_*/result.json")):
        data = json.loads(result.read_text())
        last = data["matrices"]["ade"][-1]
        seed = int(result.parent.name.removeprefix("seed_"))
        out.setdefault(result.parent.parent.name, {})[seed] = (
            sum(last) / len(last),
            data["cpu_seconds"],
        )
    return out


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("before", type=Path)
    p.add_argument("after", type=Path)
    args = p.parse_args()
    before, after = finals(args.before), finals(args.after)
    print(
        f"{'method':<16}{'seed':>6}{'before':>10}{'after':>10}{'after-before':>14}"
        f"{'CPU s before':>14}{'after':>8}"
    )
    for method in sorted(before.keys() & after.keys()):  # the methods and seeds both ran
        seeds = sorted(before[method].keys() & after[method].keys())
        for seed in seeds:
            (a, ca), (b, cb) = before[method][seed], after[method][seed]
            print(f"{method:<16}{seed:>6}{a:>10.4f}{b:>10.4f}{b - a:>+14.4f}{ca:>14.0f}{cb:>8.0f}")
        ma = [before[method][s][0] for s in seeds]
        mb = [after[method][s][0] for s in seeds]
        spread = max(ma) - min(ma)
        print(
            f"{method:<16}{'mean':>6}{statistics.mean(ma):>10.4f}{statistics.mean(mb):>10.4f}"
            f"{statistics.mean(mb) - statistics.mean(ma):>+14.4f}   (before's seeds spread "
            f"{spread:.4f})"
        )
        print(f"{'':<22}{paired(ma, mb)}")


def paired(before: list[float], after: list[float]) -> str:
    """The paired difference's mean with its 95 % t interval, and how many seeds got worse."""
    diffs = [b - a for a, b in zip(before, after, strict=True)]
    worse = sum(d > 0 for d in diffs)
    if len(diffs) < 2:
        return f"{worse} of {len(diffs)} seeds worse"
    from scipy.stats import t

    half = t.ppf(0.975, len(diffs) - 1) * statistics.stdev(diffs) / len(diffs) ** 0.5
    mean = statistics.mean(diffs)
    return (
        f"paired difference {mean:+.4f} [{mean - half:+.4f}, {mean + half:+.4f}] (95 %), "
        f"{worse} of {len(diffs)} seeds worse"
    )


if __name__ == "__main__":
    from viz.cli import run_script

    raise SystemExit(run_script(main))
