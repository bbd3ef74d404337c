"""Seed statistics for a fair comparison: a 95 % interval per cell and a paired test per method.

Methods are compared on the same seeds and the same data, so the test is paired over seeds
(Student's paired t-test, ``scipy.stats.ttest_rel``); the interval is Student's t interval of
the mean. With one seed there is no spread: both are ``None`` rather than a false certainty.
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
