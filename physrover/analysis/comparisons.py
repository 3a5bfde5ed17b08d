"""Planned comparisons: ``[[comparisons]]`` in a sweep's file (tested by ``physrover
results``), or in a claims file over a pooled runs.csv
(:mod:`physrover.analysis.claim_tests`).

Each comparison names two sets of runs by config fields, for example

```toml
[[comparisons]]
a = { method = "max-critic", curriculum_start = 1 }
b = { method = "max-critic" }          # curriculum_start as the base has it
where = { n_req = [5, 6] }             # optional: only these cells, in this order
```

and is made in every cell of the other grid fields (each ``n_req``, say; only those
``where`` lists, if it is given): the final scores of the A runs against those of the B
runs (:func:`compare_samples`: means, the exact two-sided permutation p-value, Welch's t,
Hedges' g, the fraction of runs that learn). A field one side names and the other leaves
out takes, on that other side, the value the base gives it; where the base has none (a
setting of one method's own table, say), the other side is not filtered on it. Likewise a
cell's field that a run lacks (``hybrid.period`` of a run without a hybrid) does not
filter that run, so it is compared in each cell of that field. Runs are
matched on their own configs. The p-values of a sweep's comparisons are adjusted together
by Holm's method, one family: the comparisons a study planned before it ran, stated in its
file, not chosen afterwards.
"""

from __future__ import annotations

import itertools
from typing import Any

from physrover.analysis.curve_data import format_value
from physrover.analysis.tables import compare_samples, holm_families

COLUMNS = ["comparison", "cell", "A", "B", "n_A", "n_B", "mean_A", "mean_B", "diff",
           "p_permutation", "p_holm", "family_size", "welch_t", "welch_df", "hedges_g",
           "learn_A", "learn_B"]  # fmt: skip

MIN_RUNS = 2
"""A cell with fewer runs on a side is left out: one against one has no variance to test
against (Welch's t is undefined, every permutation p is 1)."""


def _label(side: dict[str, Any]) -> str:
    return " ".join(f"{field}={format_value(value)}" for field, value in side.items())


def _sides(comparison: dict, defaults: dict[str, str]) -> dict[str, dict[str, str]]:
    """Each side's wanted values (as labels write them) of the fields either side names."""
    named = list(dict.fromkeys([*comparison["a"], *comparison["b"]]))
    wanted = {}
    for side in ("a", "b"):
        given = comparison[side]
        wanted[side] = {f: format_value(given[f]) if f in given else defaults[f]
                        for f in named if f in given or f in defaults}  # fmt: skip
    return wanted


def _cells(comparison: dict, runs: list[dict], grid: list[str], named: set[str],
           defaults: dict[str, str]) -> list[tuple[str, dict[str, str]]]:  # fmt: skip
    """The cells a comparison is made in: ``(label, {field: value})`` over the grid fields
    neither side names, those of ``where`` in its order, else those the runs have, sorted."""
    fields = [f for f in grid if f not in named]
    where = comparison.get("where")
    if where:
        listed = [[format_value(v) for v in where.get(f, [None])] for f in fields]
        combos = [dict(zip(fields, values, strict=True)) for values in itertools.product(*listed)]
        # a field where leaves out takes any value the runs have
        free = [f for f in fields if f not in where]
        if free:
            found = {tuple(run.get(f, defaults.get(f, "")) for f in free) for run in runs}
            combos = [{**c, **dict(zip(free, v, strict=True))} for c in combos
                      for v in sorted(found)]  # fmt: skip
    else:
        found = {tuple(run.get(f, defaults.get(f, "")) for f in fields) for run in runs}
        combos = [dict(zip(fields, v, strict=True)) for v in found]
        # a field some runs lack (``hybrid.period`` of a run without a hybrid) filters only
        # the runs that have it: no cell of its own for the runs without it
        combos = [c for c in combos if "" not in c.values()] or combos
    cells = [(" ".join(f"{f}={v}" for f, v in c.items()) or "all runs", c) for c in combos]
    return cells if where else sorted(cells, key=lambda cell: cell[0])


def compare_cells(runs: list[dict], comparisons, defaults: dict[str, str], grid: list[str],
                  threshold: float = 0.5) -> tuple[list[dict], list[str]]:  # fmt: skip
    """Each comparison made in each of its cells (:func:`compare_samples`, unadjusted: the
    caller forms the Holm families), with ``comparison`` (its index), ``cell``, ``values``
    (the cell's fields), ``sides`` (each side's wanted fields), ``A``, ``B``, ``n_A`` and
    ``n_B``; and the cells left out (fewer than :data:`MIN_RUNS` runs on a side). ``runs``:
    one dict per finished run, its fields (values as labels write them) and ``final_G``;
    ``defaults``: the base's value of each field (the value of a field a side leaves out);
    ``grid``: the fields whose values make the cells."""
    out, skipped = [], []
    for number, comparison in enumerate(comparisons):
        wanted = _sides(comparison, defaults)
        named = set(comparison["a"]) | set(comparison["b"])
        a, b = _label(comparison["a"]), _label(comparison["b"])
        for cell, values in _cells(comparison, runs, grid, named, defaults):
            scores = {"a": [], "b": []}
            for run in runs:
                if any(run.get(f, defaults.get(f, "")) not in (v, "") for f, v in values.items()):
                    continue  # (a run without the field is not filtered on it)
                for side, want in wanted.items():
                    if all(run.get(f, defaults.get(f)) == v for f, v in want.items()):
                        scores[side].append(float(run["final_G"]))
            if min(len(scores["a"]), len(scores["b"])) < MIN_RUNS:
                skipped.append(f"{a} vs {b}, {cell}: {len(scores['a'])} and "
                               f"{len(scores['b'])} runs, not compared (nor counted in the "
                               "Holm family)")  # fmt: skip
                continue
            out.append(
                {
                    "comparison": number,
                    "cell": cell,
                    "values": values,
                    "sides": wanted,
                    "A": a,
                    "B": b,
                    **compare_samples(scores["a"], scores["b"], threshold),
                }
            )
    return out, skipped


def planned_comparisons(
    runs: list[dict], comparisons, defaults: dict[str, str], grid: list[str], threshold: float = 0.5
) -> tuple[list[dict], list[str]]:
    """A sweep's planned comparisons (:func:`compare_cells`) as rows of :data:`COLUMNS`,
    Holm over all of them; and the cells left out."""
    rows, skipped = compare_cells(runs, comparisons, defaults, grid, threshold)
    holm_families(rows, lambda row: "all")
    return [{k: row[k] for k in COLUMNS} for row in rows], skipped


__all__ = ["COLUMNS", "MIN_RUNS", "compare_cells", "planned_comparisons"]
