"""Choose a staged tuning anew from its own runs under another rule for keeping a method's
defaults (no run: every setting the rule compares already ran on the same draws), and write it
as an artefact a board can evaluate (``sim.bench PRESET --tuned-from OUT``).

    python scripts/reselect_tuning.py noise --keep-defaults every-draw --out bench/noise-every.json
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from sim.studies.benchmark.artefacts import read_tuning, reselected  # noqa: E402


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("tuning", type=Path, help="a preset's name, a staged artefact or its board")
    p.add_argument("--keep-defaults", choices=("mean", "every-draw"), required=True)
    p.add_argument("--out", type=Path, required=True, help="the artefact to write")
    args = p.parse_args()
    _, _, before = read_tuning(args.tuning, "reselect")
    after = reselected(args.tuning, args.keep_defaults, args.out)["methods"]
    for method, entry in after.items():
        if entry.get("kept") != before[method].get("kept"):
            print(f"{method}: {before[method]['kept']} -> {entry['kept']}: {entry['settings']}")
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    from viz.cli import run_script

    raise SystemExit(run_script(main))
