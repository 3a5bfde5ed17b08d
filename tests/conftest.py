"""Shared test helpers."""

import numpy as np

from physrover.runs import read_metrics


def comparable_rows(rows):
    """metrics.csv rows without the wall time, NaN made comparable (NaN != NaN)."""
    return [
        {k: ("nan" if v != v else v) for k, v in row.items() if k != "wall_seconds"} for row in rows
    ]


def assert_same_run(a, b):
    """Run directories ``a`` and ``b`` hold the same metrics (wall time aside) and, bit for
    bit, the same state.npz: what an interrupted and resumed run must share with an
    uninterrupted one."""
    assert comparable_rows(read_metrics(a / "metrics.csv")) == comparable_rows(
        read_metrics(b / "metrics.csv")
    )
    sa, sb = np.load(a / "state.npz"), np.load(b / "state.npz")
    assert set(sa.files) == set(sb.files)
    for key in sa.files:
        np.testing.assert_array_equal(sa[key], sb[key], err_msg=key)
