"""Confidence intervals over seeds (or episodes): Student-t 95% intervals of a mean."""

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
