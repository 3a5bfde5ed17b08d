"""A sweep's planned comparisons: ``[[comparisons]]`` in its file, tested by
``physrover results``.

Each comparison names two sets of runs by config fields, for example

```toml
[[comparisons]]
a = { method = "max-critic", curriculum_start = 1 }
b = { method = "max-critic" }          # curriculum_start as the base has it
```

and is made in every cell of the sweep's other fields (each ``n_req``, say): the final
scores of the A runs against those of the B runs (their seeds; :func:`compare_samples`:
means, the exact two-sided permutation p-value, Welch's t, Hedges' g, the fraction of runs
that learn). A field a side leaves out matches the value the sweep's base gives it. The
p-values of all a sweep's comparisons are adjusted together by Holm's method, one family:
the comparisons a study planned before it ran, stated in its file, not chosen afterwards.
"""

from __future__ import annotations

from collections import defaultdict
from typing import Any

from physrover.analysis.curve_data import format_value
from physrover.analysis.tables import compare_samples, holm_families
from physrover.config import ConfigError, RunConfig

COLUMNS = ["comparison", "cell", "A", "B", "n_A", "n_B", "mean_A", "mean_B", "diff",
           "p_permutation", "p_holm", "family_size", "welch_t", "welch_df", "hedges_g",
           "learn_A", "learn_B"]  # fmt: skip


def _label(side: dict[str, Any]) -> str:
    return " ".join(f"{field}={format_value(value)}" for field, value in side.items())


def _value(row: dict, field: str, base: dict[str, str]) -> str:
    """A runs.csv row's value of ``field``: its column, or the base's where the sweep did
    not vary it."""
    value = row.get(field, "")
    return str(value) if value != "" else base[field]


def planned_comparisons(rows: list[dict], comparisons, base: RunConfig,
                        threshold: float = 0.5) -> tuple[list[dict], list[str]]:  # fmt: skip
    """The rows of :data:`COLUMNS`, one per comparison and cell, Holm over all; and the
    cells left out (fewer than 2 runs on a side). ``rows``: a sweep's runs.csv rows;
    ``base``: its base config (the value of a field no side names and the sweep did not
    vary)."""
    flat = {**base.domain.flat_dict(), **base.learn.to_dict()}
    defaults = {k: format_value(v) for k, v in flat.items()}
    grid = [c for c in (rows[0] if rows else {}) if c not in ("sweep", "run", "seed",
            "generations", "final_G", "max_eval_G", "wall_seconds", "code", "cpu")]  # fmt: skip
    out, skipped = [], []
    for number, comparison in enumerate(comparisons):
        a, b = comparison["a"], comparison["b"]
        named = set(a) | set(b)
        for field in named - set(grid) - set(defaults):
            raise ConfigError(field, "a comparison's field is not a config field of the runs")
        cells: dict[str, dict[str, list[float]]] = defaultdict(lambda: {"A": [], "B": []})
        for row in rows:
            cell = " ".join(f"{f}={row[f]}" for f in grid if f not in named) or "all runs"
            for side, want in (("A", a), ("B", b)):
                if all(_value(row, f, defaults) == format_value(v) for f, v in want.items()):
                    cells[cell][side].append(float(row["final_G"]))
        for cell, sides in sorted(cells.items()):
            if min(len(sides["A"]), len(sides["B"])) < 2:
                skipped.append(f"{_label(a)} vs {_label(b)}, {cell}: {len(sides['A'])} and "
                               f"{len(sides['B'])} runs, not compared")  # fmt: skip
                continue
            out.append({"comparison": number, "cell": cell, "A": _label(a), "B": _label(b),
                        **compare_samples(sides["A"], sides["B"], threshold)})  # fmt: skip
    holm_families(out, lambda row: "all")
    return [{k: row[k] for k in COLUMNS} for row in out], skipped


__all__ = ["COLUMNS", "planned_comparisons"]
