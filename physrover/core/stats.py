"""Statistics over seeds (or episodes): Student-t 95% intervals of a mean, the tests of
significance of the results (permutation test, Welch's t, Hedges' g, Spearman's trend) and
Holm's adjustment for a family of them."""

from __future__ import annotations

import math

import numpy as np

# t_{0.975, df} for df = 1..30; beyond, the Cornish-Fisher expansion below (error < 1e-4).
_T975 = [
    12.706, 4.303, 3.182, 2.776, 2.571, 2.447, 2.365, 2.306, 2.262, 2.228,
    2.201, 2.179, 2.160, 2.145, 2.131, 2.120, 2.110, 2.101, 2.093, 2.086,
    2.080, 2.074, 2.069, 2.064, 2.060, 2.056, 2.052, 2.048, 2.045, 2.042,
]  # fmt: skip


def t975(df: int) -> float:
    """The 97.5% quantile of Student's t with ``df`` degrees of freedom."""
    if df < 1:
        return math.nan
    if df <= 30:
        return _T975[df - 1]
    z = 1.959964
    return z + (z**3 + z) / (4 * df) + (5 * z**5 + 16 * z**3 + 3 * z) / (96 * df**2)


def mean_ci(samples: np.ndarray, axis: int = 0) -> tuple[np.ndarray, np.ndarray, int]:
    """Mean and 95% CI half-width over ``axis`` (half-width NaN for a single sample)."""
    n = samples.shape[axis]
    mean = samples.mean(axis=axis)
    if n < 2:
        return mean, np.full_like(mean, np.nan, dtype=np.float64), n
    sd = samples.std(axis=axis, ddof=1)
    return mean, t975(n - 1) * sd / math.sqrt(n), n


def permutation_test(a, b, max_exact: int = 200_000, resamples: int = 100_000, seed: int = 0):
    """Two-sided p-value of the difference of the means of samples ``a`` and ``b`` under
    the null that the labels are exchangeable (a permutation test: no normality assumed).

    Exact, over every split of the pooled samples into groups of ``len(a)`` and ``len(b)``,
    when there are at most ``max_exact`` splits (10 vs 10 seeds: 184,756); otherwise
    ``resamples`` random splits from a generator seeded with ``seed`` (the p-value then
    counts the observed split, so it is never 0). A split counts as extreme when its
    absolute difference reaches the observed one (with a relative tolerance of 1e-12).
    """
    import itertools

    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    if not (np.isfinite(a).all() and np.isfinite(b).all()):
        raise ValueError("permutation_test needs finite samples (a NaN compares as no split)")
    pooled, n_a = np.concatenate([a, b]), len(a)
    total = pooled.sum()
    observed = abs(a.mean() - b.mean())
    tolerance = 1e-12 * max(1.0, observed)
    n_splits = math.comb(len(pooled), n_a)
    if n_splits <= max_exact:
        index = np.array(list(itertools.combinations(range(len(pooled)), n_a)))
        sums = pooled[index].sum(axis=1)
        diffs = np.abs(sums / n_a - (total - sums) / len(b))
        return float(np.mean(diffs >= observed - tolerance))
    rng = np.random.default_rng(seed)
    sums = np.array([pooled[rng.permutation(len(pooled))[:n_a]].sum() for _ in range(resamples)])
    diffs = np.abs(sums / n_a - (total - sums) / len(b))
    return float((np.sum(diffs >= observed - tolerance) + 1) / (resamples + 1))


def ranks(values) -> np.ndarray:
    """Ranks 1..n of ``values``, ties given the mean of the ranks they span."""
    values = np.asarray(values, dtype=float)
    order = np.argsort(values, kind="stable")
    ranked = np.empty(len(values))
    ranked[order] = np.arange(1, len(values) + 1)
    for value in np.unique(values):  # average the ranks of each tie
        tied = values == value
        ranked[tied] = ranked[tied].mean()
    return ranked


def spearman_trend(x, y, max_exact: int = 40_320, resamples: int = 100_000, seed: int = 0):
    """Spearman's rank correlation rho of ``y`` with ``x`` (e.g. final scores against team
    size: does the score rise with it?) and its two-sided permutation p-value under the
    null that ``y`` is exchangeable across the ``x`` values.

    rho is Pearson's correlation of the ranks (ties: mean ranks, :func:`ranks`). The
    p-value is exact, over every ordering of ``y``, when there are at most ``max_exact``
    (8! = 40,320); otherwise ``resamples`` random orderings from a generator seeded with
    ``seed`` (counting the observed one, so never 0). An ordering is extreme when its
    ``|rho|`` reaches the observed one (relative tolerance 1e-12). ``x`` or ``y`` without
    spread has no trend to test: rho is NaN and p is 1.
    """
    import itertools

    x, y = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
    if len(x) != len(y) or len(x) < 3:
        raise ValueError("spearman_trend needs x and y of one length, at least 3")
    if not (np.isfinite(x).all() and np.isfinite(y).all()):
        raise ValueError("spearman_trend needs finite values")
    rx, ry = ranks(x) - (len(x) + 1) / 2, ranks(y) - (len(y) + 1) / 2
    scale = math.sqrt(float(rx @ rx) * float(ry @ ry))
    if scale == 0.0:
        return math.nan, 1.0
    rho = float(rx @ ry) / scale
    tolerance = 1e-12 * max(1.0, abs(rho))
    if math.factorial(len(y)) <= max_exact:
        orderings = ry[np.array(list(itertools.permutations(range(len(y)))))]
        return rho, float(np.mean(np.abs(orderings @ rx) / scale >= abs(rho) - tolerance))
    rng = np.random.default_rng(seed)
    extreme = 0
    for start in range(0, resamples, 10_000):
        batch = rng.permuted(np.tile(ry, (min(10_000, resamples - start), 1)), axis=1)
        extreme += int(np.sum(np.abs(batch @ rx) / scale >= abs(rho) - tolerance))
    return rho, (extreme + 1) / (resamples + 1)


def welch_t(a, b) -> tuple[float, float]:
    """Welch's t statistic of ``mean(a) - mean(b)`` and its Welch-Satterthwaite degrees of
    freedom (NaN when both samples have no spread)."""
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    va, vb = a.var(ddof=1) / len(a), b.var(ddof=1) / len(b)
    if va + vb == 0:
        return math.nan, math.nan
    t = (a.mean() - b.mean()) / math.sqrt(va + vb)
    df = (va + vb) ** 2 / (va**2 / (len(a) - 1) + vb**2 / (len(b) - 1))
    return float(t), float(df)


def hedges_g(a, b) -> float:
    """Standardised difference of means, ``(mean(a) - mean(b)) / pooled sd``, with Hedges'
    small-sample correction ``1 - 3 / (4 (n_a + n_b) - 9)``; NaN without spread."""
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    n_a, n_b = len(a), len(b)
    pooled = ((n_a - 1) * a.var(ddof=1) + (n_b - 1) * b.var(ddof=1)) / (n_a + n_b - 2)
    if pooled == 0:
        return math.nan
    return float((a.mean() - b.mean()) / math.sqrt(pooled) * (1 - 3 / (4 * (n_a + n_b) - 9)))


def learned_fraction(final_scores, threshold: float = 0.5) -> float:
    """The fraction of runs whose final score is above ``threshold`` (a run "learns")."""
    return float(np.mean(np.asarray(final_scores, dtype=float) > threshold))


def holm(p_values) -> np.ndarray:
    """Holm's step-down adjustment of a family of p-values (Holm 1979): with the m values
    sorted ascending, the i-th (from 0) becomes ``min(1, max_{j <= i} (m - j) p_(j))``,
    returned in the input's order. Rejecting where the adjusted value is below alpha keeps
    the family-wise error rate at alpha for any dependence between the tests."""
    p = np.asarray(p_values, dtype=float)
    order = np.argsort(p, kind="stable")
    scaled = (len(p) - np.arange(len(p))) * p[order]
    adjusted = np.empty_like(p)
    adjusted[order] = np.minimum(np.maximum.accumulate(scaled), 1.0)
    return adjusted
