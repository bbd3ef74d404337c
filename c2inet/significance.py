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

from c2inet.lazy import lazy_module

# a second of import, paid where a table has seeds, not by every command that imports this
stats = lazy_module("scipy.stats")
multitest = lazy_module("statsmodels.stats.multitest")

LEVEL = 0.95  # of every interval
ALPHA = 0.05  # a paired difference is marked significant below this p-value
TIE = 1e-9  # differences closer than this (metres) are rounding, not a spread


def interval(values: np.ndarray | list[float], level: float = LEVEL) -> tuple[float, float] | None:
    """Student's t interval of the mean of ``values`` (one per seed); None for one value."""
    values = np.asarray(values, dtype=float)
    if len(values) < 2:
        return None
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
            p_value = float(stats.ttest_rel(a, b).pvalue)
    return Paired(float(difference.mean()), interval(difference), p_value)


def holm(p_values: list[float | None]) -> list[float | None]:
    """Holm's adjusted p-values of a family of tests (None, a test without spread, stays None
    and does not count in the family)."""
    tested = [i for i, p in enumerate(p_values) if p is not None]
    adjusted: list[float | None] = [None] * len(p_values)
    if not tested:
        return adjusted
    tests = [p_values[i] for i in tested]
    _, corrected, _, _ = multitest.multipletests(tests, ALPHA, method="holm")
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
    sd = float(values.std(ddof=1))

    def projected(size: int) -> float:  # the interval's width at ``size`` seeds, this spread
        return 2 * float(stats.t.ppf(0.5 + LEVEL / 2, size - 1)) * sd / size**0.5

    needed = n + 1
    while needed < most and projected(needed) >= width:
        needed += 1
    return needed


def sign_flip(differences: np.ndarray | list[float]) -> float | None:
    """The two-sided p-value of a sign-flip permutation test of paired differences' mean
    (``scipy.stats.permutation_test``): exact over every sign pattern up to 16 seeds, else
    20,000 random ones (a fixed generator). It assumes only that a difference's sign is as
    likely either way under no effect, not the t-test's normality; with n seeds it cannot go
    below 2 / 2^n (0.0020 at 10 seeds, so a board of 16 Holm-adjusted tests needs 10). None
    below two seeds or without spread (where the t-test is also undefined)."""
    values = np.asarray(differences, dtype=float)
    if len(values) < 2 or (np.ptp(values) <= TIE and abs(values[0]) <= TIE):
        return None
    exact = len(values) <= 16
    result = stats.permutation_test(
        (values,),
        np.mean,
        permutation_type="samples",
        n_resamples=np.inf if exact else 20_000,
        alternative="two-sided",
        rng=np.random.default_rng(0),
    )
    return float(result.pvalue)


@dataclass(frozen=True)
class OverTunings:
    """A method-minus-reference difference over ``tunings`` independent tunings crossed with
    the same ``seeds``: the mean, its 95 % interval and p with the tuning a random effect
    (Satterthwaite's degrees of freedom ``df``)."""

    difference: float
    interval: tuple[float, float]
    p_value: float
    df: float
    tunings: int
    seeds: int


def over_tunings(differences: np.ndarray | list[list[float]]) -> OverTunings:
    """The interval and p of a mean paired difference ``differences[t][s]`` (tuning t, seed s,
    the same seeds under every tuning) that count the tuning's draw as well as the seed's:
    two-way crossed random effects (tuning, seed, residual) from the ANOVA mean squares, the
    mean's variance ``(MS_tuning + MS_seed - MS_residual) / (T S)`` (never below the residual's
    share), and Satterthwaite's degrees of freedom. Two tunings that disagree give one degree of
    freedom and a wide interval: what a verdict resting on either one alone would have hidden."""
    d = np.asarray(differences, dtype=float)
    if d.ndim != 2 or d.shape[0] < 2 or d.shape[1] < 2:
        raise ValueError(f"over tunings: expected at least 2 tunings x 2 seeds, got {d.shape}")
    t, s = d.shape
    grand = d.mean()
    ms_t = s * ((d.mean(axis=1) - grand) ** 2).sum() / (t - 1)
    ms_s = t * ((d.mean(axis=0) - grand) ** 2).sum() / (s - 1)
    residual = d - d.mean(axis=1, keepdims=True) - d.mean(axis=0, keepdims=True) + grand
    ms_e = (residual**2).sum() / ((t - 1) * (s - 1))
    combined = max(ms_t + ms_s - ms_e, ms_e, TIE**2)
    # Satterthwaite: the degrees of freedom of a sum of mean squares
    parts = [(ms_t, t - 1), (ms_s, s - 1), (ms_e, (t - 1) * (s - 1))]
    df = combined**2 / sum(m**2 / f for m, f in parts if m > 0) if ms_t + ms_s > 0 else 1.0
    df = float(min(max(df, 1.0), t * s - 1))
    se = float(np.sqrt(combined / (t * s)))
    half = float(stats.t.ppf(0.5 + LEVEL / 2, df)) * se
    p = float(2 * stats.t.sf(abs(grand) / se, df))
    return OverTunings(float(grand), (float(grand - half), float(grand + half)), p, df, t, s)


def detectable(differences: list[list[float]], power: float = 0.8) -> float | None:
    """The smallest mean paired difference a table of paired comparisons (each a list of
    per-seed differences against one reference, over the same seeds) detects with ``power`` at
    :data:`ALPHA` two-sided: ``(t_{1-ALPHA/2} + t_power) * sd / sqrt(n)``, with the median of the
    comparisons' spreads; None below two seeds or comparisons."""
    spreads = [float(np.std(d, ddof=1)) for d in differences if len(d) >= 2]
    if not spreads:
        return None
    n = min(len(d) for d in differences if len(d) >= 2)
    t = stats.t.ppf(1 - ALPHA / 2, n - 1) + stats.t.ppf(power, n - 1)
    return float(t * np.median(spreads) / np.sqrt(n))


def holm_rows(p_values: np.ndarray) -> np.ndarray:
    """:func:`holm` on every row of a matrix of p-values at once (no None): what a resampling
    needs, where statsmodels' one family a call took 45 ms a row (3 minutes for 4,000 boards).
    A test holds it equal to :func:`holm`."""
    p = np.asarray(p_values, dtype=float)
    order = np.argsort(p, axis=1)
    ranked = np.take_along_axis(p, order, axis=1) * (p.shape[1] - np.arange(p.shape[1]))
    adjusted = np.empty_like(p)
    np.put_along_axis(adjusted, order, np.minimum(np.maximum.accumulate(ranked, axis=1), 1), 1)
    return adjusted


def replication_agreement(
    differences: np.ndarray | list[list[float]],
    seeds: int | None = None,
    draws: int = 2000,
    seed: int = 0,
) -> float:
    """The share of Holm verdicts (ahead, behind, level at :data:`ALPHA`) two boards would agree
    on if they differed only in their evaluation seeds: the ceiling seed noise puts on any
    stability check, however well tuned. ``differences``: one row a method, its per-seed paired
    differences from the reference on the same seeds, taken as the truth; each of ``draws``
    pairs of boards resamples ``seeds`` seeds (default: as many) with replacement, the same
    seeds for every method (their differences share the reference's runs), and tests each
    method with the paired t-test (a sample without spread: level), Holm over the methods."""
    d = np.asarray(differences, dtype=float)
    n = d.shape[1]
    k = seeds or n
    rng = np.random.default_rng(seed)

    def verdicts() -> np.ndarray:
        sample = d[:, rng.integers(0, n, size=(draws, k))].transpose(1, 0, 2)  # draw, method, seed
        with np.errstate(divide="ignore", invalid="ignore"):
            p = np.nan_to_num(stats.ttest_1samp(sample, 0.0, axis=2).pvalue, nan=1.0)
        return np.where(holm_rows(p) < ALPHA, np.sign(sample.mean(axis=2)), 0)

    return float((verdicts() == verdicts()).mean())
