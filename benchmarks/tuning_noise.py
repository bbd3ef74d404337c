"""How noisy a tuning trial's objective is, measured on raced tunings, and the seeds a trial
would need for two tunings to choose alike.

A raced tuning (``sim.bench --race TOP``) scored each method's TOP best trials again on more
tuning seeds (each its own data and initialisation, the same seeds for every candidate): so
every candidate has one objective a draw, and the candidates of a method share their draws.
From them, per method and side by side:

- ``one draw``: the standard deviation of one candidate's objective from draw to draw;
- ``paired``: that of the difference between two candidates on the same draw (what choosing
  between them faces);
- ``curse``: how much better a candidate scored on the draw it was chosen on than on the others
  (the winner's curse of choosing the best single score);
- ``seeds a trial``: how many draws a trial would need for the standard error of a paired
  difference to fall to ``--precision`` (default 0.005 m, half the evaluation's typical seed
  spread), as ``(paired / precision) ** 2``.

    python benchmarks/tuning_noise.py [TUNING_JSON_OR_BOARD ...] [--precision 0.005]

Default: the two raced radius tunings committed under ``docs/leaderboards/radius-race/``.
"""

from __future__ import annotations

import argparse
import itertools
import json
import math
import sys
from pathlib import Path

import numpy as np

RACED = ("docs/leaderboards/radius-race/A", "docs/leaderboards/radius-race/B")


def raced_objectives(path: Path) -> dict[str, np.ndarray]:
    """Per method, its raced candidates' objectives (candidates x draws, the draw a candidate
    was chosen on first) from a ``tuning.json`` or a board folder holding one."""
    path = path / "tuning.json" if path.is_dir() else path
    tuning = json.loads(path.read_text())
    out = {}
    for method, record in tuning.items():
        rows = [r["objectives"] for r in record.get("race", [])]
        rows = [r for r in rows if None not in r]  # a diverged draw has no finite objective
        if len(rows) >= 2:
            out[method] = np.array(rows, dtype=float)
    return out


def noise(objectives: list[np.ndarray]) -> dict[str, float]:
    """The pooled spreads of one draw and of a paired difference, and the winner's curse, over
    one method's raced tunings (each candidates x draws)."""
    within, paired, curse = [], [], []
    for table in objectives:
        within += list(table.var(axis=1, ddof=1))
        for a, b in itertools.combinations(range(len(table)), 2):
            paired.append(np.var(table[a] - table[b], ddof=1))
        curse += list(table[:, 1:].mean(axis=1) - table[:, 0])
    return {
        "one_draw": math.sqrt(np.mean(within)),
        "paired": math.sqrt(np.mean(paired)),
        "curse": float(np.mean(curse)),
        "candidates": sum(len(t) for t in objectives),
    }


def refuse(why: str) -> None:
    """Bad input: one line, exit code 2."""
    print(f"error: {why}", file=sys.stderr)
    sys.exit(2)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("tunings", nargs="*", type=Path, help=f"default: {' '.join(RACED)}")
    p.add_argument("--precision", type=float, default=0.005, help="metres (0.005)")
    args = p.parse_args()
    paths = args.tunings or [Path(r) for r in RACED]
    if not 0 < args.precision < 1:
        refuse(f"--precision {args.precision:g}: expected metres in (0, 1)")
    tables: dict[str, list[np.ndarray]] = {}
    for path in paths:
        try:
            raced = raced_objectives(path)
        except (OSError, ValueError, KeyError, TypeError, AttributeError) as error:
            refuse(f"{path}: not a raced tuning's tuning.json ({error})")
        for method, table in raced.items():
            tables.setdefault(method, []).append(table)
    if not tables:
        refuse(f"{', '.join(map(str, paths))}: no raced trials (run with --race TOP)")
    print(f"{len(paths)} raced tunings; precision {args.precision} m")
    print(f"{'method':<16}{'candidates':>11}{'one draw':>10}{'paired':>9}{'curse':>9}{'seeds':>7}")
    for method, objectives in tables.items():
        n = noise(objectives)
        seeds = math.ceil((n["paired"] / args.precision) ** 2)
        print(
            f"{method:<16}{n['candidates']:>11}{n['one_draw']:>10.4f}{n['paired']:>9.4f}"
            f"{n['curse']:>+9.4f}{seeds:>7}"
        )


if __name__ == "__main__":
    from viz.cli import run_script

    raise SystemExit(run_script(main))
