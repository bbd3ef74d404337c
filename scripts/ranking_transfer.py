"""Does a ranking on one benchmark carry over to another? Two boards of the same methods (say the
five fitted crowd families against the real ETH-UCY stream, ``sim.bench ... --tuned-from`` so
both use the same settings): each method's rank by its final ADE on each (``--metric``: the point
prediction's, or the best of K, read from both boards alike), Kendall's tau-b between the two
rankings, and its 95 % bootstrap interval over seeds (each board's seeds
resampled on their own, the same draw for every method of a board, so a board's pairing holds).

    python scripts/ranking_transfer.py SIM_BOARD REAL_BOARD [--metric ade_k1|ade] [--out FILE.md]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
from scipy.stats import kendalltau

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from c2inet.errors import InputError  # noqa: E402
from c2inet.files import write_text_atomic  # noqa: E402
from c2inet.report import RANKABLE  # noqa: E402
from sim.studies.benchmark.stability import finals  # noqa: E402
from viz.cli import guarded  # noqa: E402

RESAMPLES = 2000
MIN_SEEDS = 3  # fewer seeds on either board give no interval: resampling two draws is no CI


def seed_table(board: Path, methods: list[str], metric: str = "ade_k1") -> np.ndarray:
    """(seeds, methods): each method's final ADE on the seeds every method of ``methods`` has."""
    final = finals(board, metric)
    seeds = sorted(set.intersection(*(set(final[m]) for m in methods)))
    return np.array([[final[m][s] for m in methods] for s in seeds])


def ranks(means: np.ndarray) -> np.ndarray:
    """1 for the lowest error."""
    return np.argsort(np.argsort(means)) + 1


def transfer(a: np.ndarray, b: np.ndarray, resamples: int = RESAMPLES, seed: int = 0) -> dict:
    """Kendall's tau-b between the rankings by the seed means of ``a`` and ``b`` (seeds,
    methods), with its percentile interval over ``resamples`` bootstrap draws of each board's
    seeds."""
    tau = kendalltau(a.mean(0), b.mean(0)).statistic
    rng = np.random.default_rng(seed)
    draws = [
        kendalltau(
            a[rng.integers(0, len(a), len(a))].mean(0), b[rng.integers(0, len(b), len(b))].mean(0)
        ).statistic
        for _ in range(resamples)
    ]
    low, high = np.percentile(draws, [2.5, 97.5])
    return {"tau": float(tau), "interval": (float(low), float(high))}


def read_board(board: Path, metric: str = "ade_k1") -> dict:
    """A board's final ADE per method and seed; a folder that is not a board is one line."""
    if not (board / "results.parquet").is_file():
        raise InputError(f"{board}: no results.parquet there (a benchmark's folder)")
    try:
        return finals(board, metric)
    except Exception as error:  # pyarrow and pandas raise many kinds for a damaged file
        raise InputError(
            f"{board}/results.parquet: cannot read it ({type(error).__name__})"
        ) from None


def report(
    sim: Path,
    real: Path,
    references: tuple[str, ...] = ("joint", "joint-scratch"),
    metric: str = "ade_k1",
) -> str:
    first, second = read_board(sim, metric), read_board(real, metric)
    methods = sorted((set(first) & set(second)) - set(references))
    if len(methods) < 3:
        raise InputError(f"{sim} and {real}: {len(methods)} ranked methods in common; a ranking "
                         "needs 3 or more")  # fmt: skip
    a, b = seed_table(sim, methods, metric), seed_table(real, methods, metric)
    if not len(a) or not len(b):
        raise InputError(f"{sim if not len(a) else real}: no seed that every method has")
    result = transfer(a, b)
    rank_a, rank_b = ranks(a.mean(0)), ranks(b.mean(0))
    low, high = result["interval"]
    interval = (
        f" [{low:+.2f}, {high:+.2f}]** (95 % bootstrap over each board's seeds, {RESAMPLES} draws)"
        if min(len(a), len(b)) >= MIN_SEEDS
        else f"** (no interval: a board has fewer than {MIN_SEEDS} seeds to resample)"
    )
    lines = [
        f"Ranking on `{sim}` (A, {len(a)} seeds) against `{real}` (B, {len(b)} seeds), "
        f"{len(methods)} methods by final ADE of {RANKABLE[metric]} (metres): **Kendall's tau "
        f"{result['tau']:+.2f}{interval}.",
        "",
        "| method | A: ADE | A: rank | B: ADE | B: rank | moves (B minus A) |",
        "|---|---|---|---|---|---|",
    ]
    for i in np.argsort(rank_b):
        move = int(rank_b[i] - rank_a[i])
        lines.append(
            f"| {methods[i]} | {a[:, i].mean():.3f} | {rank_a[i]} | {b[:, i].mean():.3f} | "
            f"{rank_b[i]} | {move:+d} |"
        )
    return "\n".join(lines) + "\n"


@guarded
def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("sim", type=Path)
    p.add_argument("real", type=Path)
    p.add_argument(
        "--metric", choices=tuple(RANKABLE), default="ade_k1", help="ade_k1 (default) or ade"
    )
    p.add_argument("--out", type=Path, help="also write the table here")
    args = p.parse_args(argv)
    text = report(args.sim, args.real, metric=args.metric)
    print(text, end="")
    if args.out:
        try:
            write_text_atomic(args.out, text)
        except OSError as error:
            raise InputError(f"--out {args.out}: cannot write it ({error.strerror})") from None
    return 0


if __name__ == "__main__":
    sys.exit(main())
