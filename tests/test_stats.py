"""Confidence intervals and tests of significance, against hand-worked values."""

import itertools
import math

import numpy as np
import pytest

from physrover.core.stats import (
    hedges_g,
    holm,
    learned_fraction,
    mean_ci,
    permutation_test,
    ranks,
    spearman_trend,
    welch_t,
)


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


def test_spearman_by_hand():
    # no ties: d = (-1, 1, -1, 1, 0), rho = 1 - 6 * 4 / (5 * 24) = 0.8; of the 120
    # orderings, 8 have sum d^2 <= 4 (rho >= 0.8: 1, 4 and 3 with sums 0, 2, 4) and 8
    # mirror them (rho <= -0.8): p = 16 / 120 (Spearman's tables: P(rho >= 0.8) = 0.067)
    rho, p = spearman_trend([1, 2, 3, 4, 5], [2, 1, 4, 3, 5])
    assert rho == pytest.approx(0.8) and p == pytest.approx(16 / 120)
    # ties: ranks (1.5, 1.5, 3.5, 3.5) and (1, 2.5, 2.5, 4), centred (-1, -1, 1, 1) and
    # (-1.5, 0, 0, 1.5): rho = 3 / sqrt(4 * 4.5)
    assert list(ranks([0, 1, 1, 2])) == [1.0, 2.5, 2.5, 4.0]
    rho, _ = spearman_trend([1, 1, 2, 2], [0, 1, 1, 2])
    assert rho == pytest.approx(3 / math.sqrt(18))
    # a score that falls with team size is a trend too (two-sided); no spread: none
    assert spearman_trend([6, 9, 12], [3.0, 2.0, 1.0]) == (
        pytest.approx(-1.0),
        pytest.approx(2 / 6),
    )
    assert spearman_trend([6, 9, 12], [0.0, 0.0, 0.0])[1] == 1.0


@pytest.mark.parametrize("seed", range(4))
@pytest.mark.parametrize("decimals", [1, 0])  # 0: ties in the scores too
def test_spearman_p_matches_a_plain_enumeration_and_its_sampled_estimate(seed, decimals):
    rng = np.random.default_rng(seed)
    x = np.repeat([6.0, 9.0, 12.0], 2)  # team sizes, 2 seeds each
    y = np.round(x / 3 + rng.normal(0, 2, 6), decimals)

    def rho(y_order):  # Pearson's correlation of mean ranks, written out
        rx, ry = ranks(x), ranks(y_order)
        rx, ry = rx - rx.mean(), ry - ry.mean()
        return (rx * ry).sum() / math.sqrt((rx**2).sum() * (ry**2).sum())

    observed = rho(y)
    count = sum(abs(rho(np.array(o))) >= abs(observed) - 1e-12 for o in itertools.permutations(y))
    exact = spearman_trend(x, y)
    assert exact == (pytest.approx(observed), pytest.approx(count / 720))
    sampled = spearman_trend(x, y, max_exact=0, resamples=50_000, seed=1)
    assert sampled[1] == pytest.approx(count / 720, abs=0.01)  # sd of the estimate < 0.0023
    assert sampled == spearman_trend(x, y, max_exact=0, resamples=50_000, seed=1)  # seeded
