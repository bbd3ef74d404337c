"""``python -m sim.bench PRESET``: the fair benchmark, tuning then evaluation then a leaderboard.

The study ``bench`` (``sim/studies/benchmark/``) under its own command: ``python -m sim.study
bench PRESET`` runs the same; ``c2i-bench`` is its console script.
"""

import sys

from sim.study import command

main = command("bench", "sim.bench")

if __name__ == "__main__":
    sys.exit(main())
