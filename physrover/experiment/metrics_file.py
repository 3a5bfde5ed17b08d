"""A run's metrics.csv: its rows read (:func:`read_metrics`) and written as text
(:func:`metrics_text`; the store writes it atomically,
:func:`physrover.experiment.store.write_metrics`), one row per generation of the CCEA or
iteration of a trainer, columns as each learner names them."""

from __future__ import annotations

import csv
import io
import math
from pathlib import Path


def read_metrics(path: Path) -> list[dict[str, float]]:
    """The rows of a metrics.csv, generations counted from 1; a trainer's rows (first
    column ``iteration``) also carry their iteration as ``generation``, the position every
    reader of runs uses.

    physrover 0.1.0 counted the rows' generations from 0; such files (first row 0) are read
    shifted by one, so old and new runs plot on one axis. A last line without its line end
    (a process killed while writing it) is not a row.
    """
    with open(path, newline="") as f:
        text = f.read()
    lines = text.splitlines(keepends=True)
    if lines and not lines[-1].endswith("\n"):
        lines.pop()
    rows = [{k: float(v) for k, v in row.items()} for row in csv.DictReader(lines)]
    if rows and "generation" not in rows[0] and "iteration" in rows[0]:
        for row in rows:  # a trainer's run: its rows' position under the common name too
            row["generation"] = row["iteration"]
    if rows and rows[0]["generation"] == 0:
        for row in rows:
            row["generation"] += 1
    return rows


def metrics_columns(path: Path) -> list[str] | None:
    """The header of the metrics.csv at ``path``, or None if there is none."""
    try:
        with open(path, newline="") as f:
            return next(csv.reader(f), None)
    except OSError:
        return None


def metrics_text(rows: list[dict], header: list[str]) -> str:
    """The CSV text of ``rows`` under ``header`` (each value by :func:`format_value`)."""
    text = io.StringIO(newline="")
    writer = csv.DictWriter(text, fieldnames=header)
    writer.writeheader()
    for row in rows:
        writer.writerow({k: format_value(row[k]) for k in header})
    return text.getvalue()


def format_value(value: float) -> str:
    if isinstance(value, int) or (
        isinstance(value, float) and value.is_integer() and abs(value) < 1e15
    ):
        return str(int(value))
    return "nan" if isinstance(value, float) and math.isnan(value) else repr(float(value))
