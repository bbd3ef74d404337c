"""Seed statistics for a fair comparison: a 95 % interval per cell, a paired test per method,
Holm's correction over a board of tests, and how many seeds a paired interval needs.

Methods are compared on the same seeds and the same data, so the test is paired over seeds
(Student's paired t-test, ``scipy.stats.ttest_rel``); the interval is Student's t interval of
the mean. With one seed there is no spread: both are ``None`` rather than a false certainty.
A board tests every method against one reference, so its p-values are adjusted together
(Holm's step-down, ``statsmodels``), which holds the chance of any false claim at ``ALPHA``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

LEVEL = 0.95  # of every interval
ALPHA = 0.05  # a paired difference is marked significant below this p-value
TIE = 1e-9  # differences closer than this (metres) are rounding, not a spread


def interval(values: np.ndarray | list[float], level: float = LEVEL) -> tuple[float, float] | None:
    """Student's t interval of the mean of ``values`` (one per seed); None for one value."""
    values = np.asarray(values, dtype=float)
    if len(values) < 2:
        return None
    from scipy import stats  # a second of import: only where a table has seeds

    mean, sem = values.mean(), stats.sem(values)
    if sem == 0:
        return float(mean), float(mean)
    low, high = stats.t.interval(level, len(values) - 1, loc=mean, scale=sem)
    return float(low), float(high)


@dataclass(frozen=True)
class Paired:
    """``method`` minus ``reference`` over the same seeds: mean difference, its interval, the
    paired t-test's two-sided p-value, and whether it is below :data:`ALPHA`."""

    difference: float
    interval: tuple[float, float] | None
    p_value: float | None

    @property
    def significant(self) -> bool:
        return self.p_value is not None and self.p_value < ALPHA


def paired(method: list[float], reference: list[float]) -> Paired:
    """Compare one method's per-seed values with a reference's on the same seeds."""
    a, b = np.asarray(method, dtype=float), np.asarray(reference, dtype=float)
    if a.shape != b.shape:
        raise ValueError(f"paired test: {len(a)} seeds against {len(b)}; seeds must match")
    difference = a - b
    p_value = None
    if len(a) >= 2:
        if np.ptp(difference) <= TIE:  # no spread: t is undefined, the sign is sure
            p_value = 1.0 if abs(difference[0]) <= TIE else 0.0
        else:
            from scipy import stats

            p_value = float(stats.ttest_rel(a, b).pvalue)
    return Paired(float(difference.mean()), interval(difference), p_value)


def holm(p_values: list[float | None]) -> list[float | None]:
    """Holm's adjusted p-values of a family of tests (None, a test without spread, stays None
    and does not count in the family)."""
    tested = [i for i, p in enumerate(p_values) if p is not None]
    adjusted: list[float | None] = [None] * len(p_values)
    if not tested:
        return adjusted
    from statsmodels.stats.multitest import multipletests

    _, corrected, _, _ = multipletests([p_values[i] for i in tested], ALPHA, method="holm")
    for i, p in zip(tested, corrected, strict=True):
        adjusted[i] = float(p)
    return adjusted


def interval_width(values: np.ndarray | list[float], level: float = LEVEL) -> float:
    """The width of Student's t interval of the mean of ``values``; infinite below two."""
    bounds = interval(values, level)
    return float("inf") if bounds is None else bounds[1] - bounds[0]


def seeds_to_narrow(
    differences: np.ndarray | list[float], width: float, most: int, least: int = 3
) -> int:
    """How many seeds in all a paired comparison should have for the 95 % interval of its mean
    difference to be narrower than ``width``: ``len(differences)`` once it is (or at ``most``),
    else the projection from the spread so far (Student's t at that size), at least one more and
    at most ``most``. Below ``least`` seeds the spread is not trusted: ``least``."""
    values = np.asarray(differences, dtype=float)
    n = len(values)
    if n >= most or (n >= least and interval_width(values) < width):
        return n
    if n < least:
        return least
    from scipy import stats

    sd = float(values.std(ddof=1))

    def projected(size: int) -> float:  # the interval's width at ``size`` seeds, this spread
        return 2 * float(stats.t.ppf(0.5 + LEVEL / 2, size - 1)) * sd / size**0.5

    needed = n + 1
    while needed < most and projected(needed) >= width:
        needed += 1
    return needed
