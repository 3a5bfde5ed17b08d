"""A committed figure drawn again from the CSV written beside it (``physrover curves
FILE.csv``), with today's plotting code: the runs a figure was made from rarely outlive
their machine, its numbers do.

:func:`read_table` is the inverse of :func:`physrover.analysis.curve_data.write_csv` (the
same bytes when written again: a test); a learning-curve CSV (:data:`CURVE_COLUMNS`) is
drawn by :func:`~physrover.analysis.plots.plot_curves`, a final-score CSV (``group, X, mean,
ci95_half_width, n``) by :func:`~physrover.analysis.plots.plot_final`. The CSVs keep no
maximum of G, so the redrawn figure has no dashed line at it and its bands are not
clipped; a group's colour follows the method its label starts with.
"""

from __future__ import annotations

import csv
from collections import defaultdict
from pathlib import Path

import numpy as np

from physrover.analysis.curve_data import CURVE_COLUMNS, Table
from physrover.analysis.plots import Plot, plot_curves, plot_final
from physrover.config import ConfigError


def read_table(path: str | Path) -> Table:
    """The table a curves or final-score CSV at ``path`` holds."""
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    if not rows or len(rows[0]) < 5 or rows[0][0] != "group":
        raise ConfigError(str(path), "not a CSV that physrover curves or results wrote "
                          "(its first column must be 'group')")  # fmt: skip
    header, body = rows[0], rows[1:]
    curves = header == CURVE_COLUMNS
    if not curves and header[2:] != ["mean", "ci95_half_width", "n"]:
        raise ConfigError(str(path), f"unknown columns {', '.join(header)}")
    by_group: dict[str, list[list[str]]] = defaultdict(list)
    for row in body:
        by_group[row[0]].append(row)
    table = Table("generation" if curves else header[1])
    for group, lines in by_group.items():
        column = {name: [line[i] for line in lines] for i, name in enumerate(header)}

        def floats(name, column=column):
            return np.array([float(v) for v in column[name]])

        cols = {"mean": floats("mean"), "ci": floats("ci95_half_width"),
                "method": group.split()[0]}  # fmt: skip
        n = np.array([int(v) for v in column["n"]])
        if curves:
            cols["generation"] = floats("generation").astype(np.int64)
            if all(column["episodes"]):
                cols["episodes"] = floats("episodes").astype(np.int64)
            cols["raw_mean"], cols["raw_ci"] = floats("raw_mean"), floats("raw_ci95_half_width")
            cols["smooth"] = int(column["smooth_window"][0])
            cols["n"] = int(n[0]) if (n == n[0]).all() else n
        else:
            cols["x"], cols["n"] = floats(header[1]), n
        table[group] = cols
    return table


def redraw(path: str | Path, out: str | Path | None = None, title: str = "") -> Plot:
    """Draw the CSV at ``path`` again, to ``out`` (default: the PNG of the same name beside
    it; the CSV is written again beside ``out``, the same numbers)."""
    table = read_table(path)
    png = Path(out) if out else Path(path).with_suffix(".png")
    if table.x == "generation":
        plot_curves(table, png, title)
    else:
        plot_final(table, png, table.x, title)
    return Plot(png, png.with_suffix(".csv"), table, [])


__all__ = ["read_table", "redraw"]
