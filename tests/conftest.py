"""Shared test helpers."""


def comparable_rows(rows):
    """metrics.csv rows without the wall time, NaN made comparable (NaN != NaN)."""
    return [
        {k: ("nan" if v != v else v) for k, v in row.items() if k != "wall_seconds"} for row in rows
    ]
