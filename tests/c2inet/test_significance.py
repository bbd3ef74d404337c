"""The seed statistics: intervals, a paired test that finds a planted difference only, Holm's
correction over a board, and how many seeds a paired interval needs."""

import numpy as np
import pytest

from c2inet.evaluation import VARIANT_METRICS
from c2inet.report import compare, comparison_rows, summarise
from c2inet.significance import holm, interval, interval_width, paired, seeds_to_narrow


def test_the_interval_holds_the_mean_and_widens_with_the_spread():
    low, high = interval([1.0, 2.0, 3.0])
    assert low < 2.0 < high and high - low == pytest.approx(2 * 4.303 * 1 / np.sqrt(3), 1e-3)
    wide = interval([0.0, 2.0, 4.0])
    assert wide[1] - wide[0] > high - low
    assert interval([1.0]) is None


def test_the_paired_test_flags_a_planted_difference_and_not_a_null_one():
    rng = np.random.default_rng(0)
    seed_effect = rng.normal(0.3, 0.05, 5)  # seeds vary more than the planted difference
    planted = paired(seed_effect + 0.02 + rng.normal(0, 0.002, 5), seed_effect)
    assert planted.significant and planted.difference == pytest.approx(0.02, abs=0.003)
    assert planted.interval[0] > 0
    nulls = [paired(seed_effect + rng.normal(0, 0.01, 5), seed_effect) for _ in range(200)]
    false_alarms = np.mean([t.significant for t in nulls])
    assert 0.0 < false_alarms < 0.12  # about the 5 % a test at 0.05 allows
    unpaired_blind = paired(seed_effect + 0.02, rng.permutation(seed_effect))
    assert not unpaired_blind.significant  # the pairing is what finds it
    with pytest.raises(ValueError, match="seeds must match"):
        paired([1.0, 2.0], [1.0])
    assert paired([1.0], [2.0]).p_value is None


def runs_of(offset: float, seeds: int = 5) -> dict:
    """summarise()'s output for a method whose error is the seed's noise plus ``offset``."""
    rng = np.random.default_rng(1)  # the same seeds for every method: paired
    runs = []
    for noise in rng.normal(0, 0.05, seeds):
        base = np.array([[0.3, 0.5], [0.35, 0.32]]) + noise + offset
        runs.append({m: base.copy() for m in VARIANT_METRICS})
    return summarise(runs, [[{"memory_floats": 10}, {"memory_floats": 20}]] * seeds)


def test_the_comparison_marks_only_the_method_that_differs():
    methods = {"finetune": runs_of(0.0), "better": runs_of(-0.03), "same": runs_of(0.0)}
    comparison = compare(methods)
    assert comparison["better"]["final_ade_k1"]["significant"]
    assert comparison["better"]["final_ade_k1"]["difference"] == pytest.approx(-0.03)
    assert not comparison["same"]["final_ade_k1"]["significant"]
    assert comparison["better"]["memory_floats"] == 20
    rows = comparison_rows(comparison, "ade_k1")
    assert rows[2][0] == "better" and rows[2][3].endswith("*") and not rows[3][3].endswith("*")
    assert compare({"better": methods["better"]}) == {}  # no reference, no comparison


def test_holm_turns_a_borderline_p_value_of_a_board_into_a_non_significant_one():
    """A p of 0.03 alone is significant; as the smallest of three it is multiplied by 3, and
    a larger one is held to at least the smaller's adjusted value (Holm's step-down)."""
    assert holm([0.03]) == [pytest.approx(0.03)]
    adjusted = holm([0.03, 0.2, None, 0.04])
    assert adjusted[0] == pytest.approx(0.09) and adjusted[0] > 0.05  # 3 tests: 3 x 0.03
    assert adjusted[3] == pytest.approx(0.09)  # 2 x 0.04 = 0.08, held to the step before
    assert adjusted[1] == pytest.approx(0.2) and adjusted[2] is None
    assert holm([None, None]) == [None, None]


def test_seeds_are_added_until_the_interval_is_narrow_and_not_after():
    rng = np.random.default_rng(3)
    noisy = rng.normal(0.0, 0.02, 8)
    assert interval_width(noisy) > 0.01
    needed = seeds_to_narrow(noisy, 0.01, 1000)
    assert 8 < needed < 1000
    narrow = rng.normal(0.0, 0.002, 8)
    assert interval_width(narrow) < 0.01 and seeds_to_narrow(narrow, 0.01, 100) == 8
    assert seeds_to_narrow(noisy, 0.01, 12) == 12  # at most the maximum
    assert seeds_to_narrow(noisy, 0.01, 8) == 8  # the maximum reached: no more
    assert seeds_to_narrow(noisy[:2], 0.01, 30) == 3  # too few to trust the spread
    # the projection is the smallest size whose t interval at this spread is narrow enough
    from scipy import stats

    sd = noisy.std(ddof=1)
    width = [2 * stats.t.ppf(0.975, n - 1) * sd / np.sqrt(n) for n in (needed - 1, needed)]
    assert width[0] >= 0.01 > width[1]


def test_the_sign_flip_test_is_exact_and_needs_ten_seeds_for_a_board_of_sixteen():
    from c2inet.significance import sign_flip

    assert sign_flip([0.01] * 10) == pytest.approx(2 / 2**10)  # every sign the same: the floor
    assert sign_flip([0.01] * 8) * 16 > 0.05  # at 8 seeds Holm over 16 can never star it
    assert sign_flip([0.01] * 10) * 16 < 0.05
    symmetric = [0.02, -0.02, 0.01, -0.01, 0.03, -0.03]
    assert sign_flip(symmetric) == pytest.approx(1.0)
    assert sign_flip([0.0, 0.0, 0.0]) is None and sign_flip([0.1]) is None
    heavy = [0.001, 0.002, -0.001, 0.001, 0.9, 0.002, 0.001, -0.002]  # one wild seed
    assert sign_flip(heavy) > 0.05  # the permutation test is not carried by one seed


def test_the_interval_over_tunings_widens_when_a_planted_second_tuning_disagrees():
    from c2inet.significance import over_tunings

    rng = np.random.default_rng(3)
    seeds = rng.normal(0.0, 0.004, 10)
    first = -0.02 + seeds + rng.normal(0, 0.002, 10)
    agreeing = over_tunings([first, -0.02 + seeds + rng.normal(0, 0.002, 10)])
    disagreeing = over_tunings([first, +0.01 + seeds + rng.normal(0, 0.002, 10)])
    assert agreeing.interval[1] < 0 and agreeing.p_value < 0.01 and agreeing.df > 5
    low, high = disagreeing.interval
    assert low < 0 < high and high - low > 5 * (agreeing.interval[1] - agreeing.interval[0])
    assert disagreeing.df < 2 and (disagreeing.tunings, disagreeing.seeds) == (2, 10)
    one = paired(list(first), [0.0] * 10)  # one tuning alone: narrow, and blind to the other
    assert one.interval[1] < 0
    with pytest.raises(ValueError, match="at least 2 tunings"):
        over_tunings([first])


def test_the_detectable_effect_shrinks_with_seeds_as_one_over_their_root():
    from c2inet.significance import detectable

    rng = np.random.default_rng(5)
    few = detectable([list(rng.normal(0, 0.01, 8)) for _ in range(5)])
    many = detectable([list(rng.normal(0, 0.01, 32)) for _ in range(5)])
    assert 0.006 < few < 0.016 and many < few / 1.8  # about 2.9 sd / sqrt(n)
    assert detectable([[0.1]]) is None


def test_seed_noise_alone_caps_how_often_two_boards_agree_and_more_seeds_raise_the_cap():
    from c2inet.significance import replication_agreement

    rng = np.random.default_rng(7)
    noise = rng.normal(0.0, 0.01, (6, 10))
    clear = noise - noise.mean(axis=1, keepdims=True) + [[0.05], [-0.05], [0.06], [0], [0], [0]]
    assert replication_agreement(clear) > 0.95  # far from the threshold or at 0: the same verdict
    at_threshold = noise - noise.mean(axis=1, keepdims=True)
    at_threshold += np.sign(rng.normal(size=(6, 1))) * 0.0085  # about a Holm p of 0.05
    cap = replication_agreement(at_threshold)
    assert 0.4 < cap < 0.85  # a coin toss for a method whose p sits at the threshold
    assert replication_agreement(at_threshold, seeds=40) > cap + 0.1
    assert replication_agreement(at_threshold) == cap  # a fixed generator: the same figure


def test_holm_on_rows_is_holm_on_each_row():
    from c2inet.significance import holm_rows

    rng = np.random.default_rng(11)
    p = rng.uniform(0, 0.1, (20, 7))
    np.testing.assert_allclose(holm_rows(p), [holm(list(row)) for row in p])
