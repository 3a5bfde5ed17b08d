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
that learn). A field one side names and the other leaves out takes, on that other side,
the value the sweep's base gives it; runs are matched on their own configs. The
p-values of all a sweep's comparisons are adjusted together by Holm's method, one family:
the comparisons a study planned before it ran, stated in its file, not chosen afterwards.
"""

from __future__ import annotations

from collections import defaultdict
from typing import Any

from physrover.analysis.curve_data import format_value, run_fields
from physrover.analysis.tables import compare_samples, holm_families
from physrover.config import ConfigError, RunConfig

COLUMNS = ["comparison", "cell", "A", "B", "n_A", "n_B", "mean_A", "mean_B", "diff",
           "p_permutation", "p_holm", "family_size", "welch_t", "welch_df", "hedges_g",
           "learn_A", "learn_B"]  # fmt: skip


def _label(side: dict[str, Any]) -> str:
    return " ".join(f"{field}={format_value(value)}" for field, value in side.items())


def planned_comparisons(runs: list[dict], comparisons, base: RunConfig, grid: list[str],
                        threshold: float = 0.5) -> tuple[list[dict], list[str]]:  # fmt: skip
    """The rows of :data:`COLUMNS`, one per comparison and cell, Holm over all; and the
    cells left out (fewer than 2 runs on a side). ``runs``: one dict per finished run of
    the sweep, its config fields (values as group labels write them) and ``final_G``;
    ``base``: the sweep's base config (the value of a field a side leaves out); ``grid``:
    the fields whose values make the sweep's cells."""
    defaults = {k: format_value(v) for k, v in run_fields(base).items()}
    out, skipped = [], []
    for number, comparison in enumerate(comparisons):
        named = list(dict.fromkeys([*comparison["a"], *comparison["b"]]))
        wanted = {}
        for side in ("a", "b"):
            given = comparison[side]
            for field in named:
                if field not in given and field not in defaults:
                    raise ConfigError(field, f"comparison {number} names it on one side "
                                      "only and the base has none: name it on both")  # fmt: skip
            wanted[side] = {f: format_value(given[f]) if f in given else defaults[f]
                            for f in named}  # fmt: skip
        cells: dict[str, dict[str, list[float]]] = defaultdict(lambda: {"a": [], "b": []})
        for run in runs:
            cell = " ".join(f"{f}={run.get(f, defaults.get(f, ''))}" for f in grid
                            if f not in named) or "all runs"  # fmt: skip
            for side, want in wanted.items():
                if all(run.get(f, defaults.get(f)) == v for f, v in want.items()):
                    cells[cell][side].append(float(run["final_G"]))
        a, b = _label(comparison["a"]), _label(comparison["b"])
        for cell, sides in sorted(cells.items()):
            if min(len(sides["a"]), len(sides["b"])) < 2:
                skipped.append(f"{a} vs {b}, {cell}: {len(sides['a'])} and {len(sides['b'])} "
                               "runs, not compared (nor counted in the Holm family)")  # fmt: skip
                continue
            out.append({"comparison": number, "cell": cell, "A": a, "B": b,
                        **compare_samples(sides["a"], sides["b"], threshold)})  # fmt: skip
    holm_families(out, lambda row: "all")
    return [{k: row[k] for k in COLUMNS} for row in out], skipped


__all__ = ["COLUMNS", "planned_comparisons"]
