"""Confidence intervals and tests of significance, against hand-worked values."""

import itertools
import math

import numpy as np
import pytest

from physrover.stats import hedges_g, holm, learned_fraction, mean_ci, permutation_test, welch_t


def test_mean_ci_hand_worked():
    mean, half, n = mean_ci(np.array([1.0, 2.0, 3.0]))
    assert (mean, n) == (2.0, 3) and half == pytest.approx(4.303 * 1.0 / math.sqrt(3))


def test_exact_permutation_test_by_hand():
    # a = (3, 4), b = (0, 1): of the 6 splits of {0, 1, 3, 4} into pairs, the observed
    # |3.5 - 0.5| = 3 is reached by the split and its mirror: p = 2 / 6.
    assert permutation_test([3.0, 4.0], [0.0, 1.0]) == pytest.approx(2 / 6)
    # identical groups: every split is at least as extreme as 0
    assert permutation_test([1.0, 1.0, 1.0], [1.0, 1.0, 1.0]) == 1.0
    # 5 vs 5 fully separated: the two extreme splits of 252
    assert permutation_test([5, 6, 7, 8, 9], [0, 1, 2, 3, 4]) == pytest.approx(2 / 252)


def test_permutation_test_matches_a_plain_enumeration():
    rng = np.random.default_rng(0)
    a, b = rng.normal(1, 1, 4), rng.normal(0, 1, 5)
    pooled, observed = np.concatenate([a, b]), abs(a.mean() - b.mean())
    extreme = 0
    splits = list(itertools.combinations(range(9), 4))
    for idx in splits:
        rest = [i for i in range(9) if i not in idx]
        extreme += abs(pooled[list(idx)].mean() - pooled[rest].mean()) >= observed - 1e-12
    assert permutation_test(a, b) == pytest.approx(extreme / len(splits))
    sampled = permutation_test(a, b, max_exact=10, resamples=20_000)
    assert sampled == pytest.approx(extreme / len(splits), abs=0.02)


def test_welch_and_hedges_by_hand():
    a, b = [2.0, 4.0, 6.0], [1.0, 2.0, 3.0]  # means 4, 2; variances 4, 1
    t, df = welch_t(a, b)
    assert t == pytest.approx(2.0 / math.sqrt(4 / 3 + 1 / 3))
    assert df == pytest.approx((5 / 3) ** 2 / ((4 / 3) ** 2 / 2 + (1 / 3) ** 2 / 2))
    # pooled sd sqrt((2*4 + 2*1) / 4) = sqrt(2.5); correction 1 - 3 / (4*6 - 9) = 0.8
    assert hedges_g(a, b) == pytest.approx(2.0 / math.sqrt(2.5) * 0.8)
    assert math.isnan(hedges_g([1.0, 1.0], [1.0, 1.0])) and math.isnan(welch_t([0, 0], [0, 0])[0])


def test_learned_fraction():
    assert learned_fraction([0.0, 0.4, 0.6, 7.0]) == 0.5


def test_holm_by_hand():
    # sorted 0.005, 0.01, 0.03, 0.04 -> x4, x3, x2, x1 = 0.02, 0.03, 0.06, 0.04 -> running
    # maximum 0.02, 0.03, 0.06, 0.06, back in the input's order
    np.testing.assert_allclose(holm([0.01, 0.04, 0.03, 0.005]), [0.03, 0.06, 0.06, 0.02])
    np.testing.assert_allclose(holm([0.5, 0.6]), [1.0, 1.0])  # capped at 1
    np.testing.assert_allclose(holm([0.0079]), [0.0079])  # a family of one: unchanged
    assert holm([]).shape == (0,)
