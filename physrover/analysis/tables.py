"""Final scores as a paper's table, and two settings compared with tests of significance.

``physrover table RUN_DIRS [--compare FIELD=A,B] [--last N] [--out PREFIX]``.

A run's *final score* is its mean eval G over its last ``last`` generations (RESULTS.md
uses 50). Runs are grouped as the curves are (:mod:`physrover.analysis.curve_data`: equal
configs but for the seed), each run one sample. :func:`cells` gives each group's n, mean final score
with its Student-t 95% half-width, range, and the fraction of runs that *learn* (final score
above ``threshold``, 0.5 by default). :func:`comparisons` sets value A of one field against
value B in every *cell* (a combination of the other fields that differ), e.g. the max
critic against the mean critic at each coupling and team size, with
:func:`compare_samples`; the comparisons made form one family, whose permutation p-values
are adjusted by Holm's method (:func:`holm_families`), since a table of m comparisons at
alpha each would otherwise find about alpha m differences where there are none.
"""

from __future__ import annotations

import csv
import math
from collections import defaultdict
from pathlib import Path

import numpy as np

from physrover.analysis.curve_data import Run, differing_fields, final_score, format_value
from physrover.config import ConfigError, parse_override
from physrover.core.stats import (
    hedges_g,
    holm,
    learned_fraction,
    mean_ci,
    permutation_test,
    welch_t,
)

CELL_COLUMNS = ["group", "n", "mean", "ci95_half_width", "min", "max", "learned"]
COMPARE_COLUMNS = [
    "cell", "A", "B", "n_A", "n_B", "mean_A", "mean_B", "diff", "p_permutation", "p_holm",
    "family_size", "welch_t", "welch_df", "hedges_g", "learn_A", "learn_B",
]  # fmt: skip


def scored(runs: list[Run], last: int) -> tuple[list[tuple[Run, float]], list[str]]:
    """(run, final score) of each run that has one, and a message for each left out."""
    kept, messages = [], []
    for run in runs:
        score = final_score(run, last)
        if math.isnan(score):
            what = "no generations yet" if not len(run.eval_G) else f"no eval G in its last {last}"
            messages.append(f"{run.path}: {what}, left out")
        else:
            kept.append((run, score))
    return kept, messages


def compare_samples(a, b, threshold: float = 0.5) -> dict:
    """Sample ``a`` against sample ``b`` (one final score per seed): sizes, means and their
    difference, the two-sided permutation p-value (:func:`physrover.core.stats.permutation_test`:
    exact over every split up to 200,000 splits, 10 vs 10 seeds; else 100,000 random ones),
    Welch's t and degrees of freedom, Hedges' g, and each side's fraction of runs above
    ``threshold``."""
    t, df = welch_t(a, b)
    return {
        "n_A": len(a),
        "n_B": len(b),
        "mean_A": float(np.mean(a)),
        "mean_B": float(np.mean(b)),
        "diff": float(np.mean(a) - np.mean(b)),
        "p_permutation": permutation_test(a, b),
        "welch_t": t,
        "welch_df": df,
        "hedges_g": hedges_g(a, b),
        "learn_A": learned_fraction(a, threshold),
        "learn_B": learned_fraction(b, threshold),
    }


def holm_families(rows: list[dict], family) -> None:
    """Set each row's ``p_holm`` (its ``p_permutation`` adjusted by Holm's method within its
    family) and ``family_size`` (m), in place; ``family(row)`` names a row's family."""
    families = defaultdict(list)
    for row in rows:
        families[family(row)].append(row)
    for members in families.values():
        adjusted = holm([row["p_permutation"] for row in members])
        for row, p in zip(members, adjusted, strict=True):
            row["p_holm"], row["family_size"] = float(p), len(members)


def length_messages(runs: list[Run]) -> list[str]:
    """A message for each group whose runs (those with generations) differ in length (an
    unfinished run among them: each run is scored on its own last generations)."""
    lengths: dict[str, list[int]] = defaultdict(list)
    for run in runs:
        if len(run.eval_G):
            lengths[run.group].append(len(run.eval_G))
    return [f"{group}: runs of {min(n)} to {max(n)} generations, each scored on its own end"
            for group, n in lengths.items() if min(n) != max(n)]  # fmt: skip


def cells(runs: list[Run], last: int, threshold: float = 0.5) -> list[dict]:
    """One row per group of ``runs`` (in their order of first appearance): see
    :data:`CELL_COLUMNS`."""
    groups: dict[str, list[float]] = defaultdict(list)
    for run, score in scored(runs, last)[0]:
        groups[run.group].append(score)
    rows = []
    for group, scores in groups.items():
        mean, ci, n = mean_ci(np.array(scores))
        rows.append({"group": group, "n": n, "mean": float(mean), "ci95_half_width": float(ci),
                     "min": min(scores), "max": max(scores),
                     "learned": learned_fraction(scores, threshold)})  # fmt: skip
    return rows


def parse_compare(text: str) -> tuple[str, str, str]:
    """``--compare FIELD=A,B`` -> (FIELD, A, B) as written (:func:`comparisons` also
    matches A and B read as values and written as group labels write them: ``0.50`` is
    ``0.5``, ``1e-3`` is ``0.001``)."""
    field, sep, values = text.partition("=")
    a, comma, b = values.partition(",")
    if not (sep and comma and field.strip() and a.strip() and b.strip()) or "," in b:
        raise ConfigError("--compare", f"expected FIELD=A,B (e.g. method=max-critic,D), got "
                          f"{text!r}")  # fmt: skip
    return field.strip(), a.strip(), b.strip()


def _as_label(text: str) -> str:
    """``text`` read as --set reads a value (TOML, else the text) and written as a label."""
    return format_value(parse_override(f"v={text}")[1])


def comparisons(
    runs: list[Run], field: str, a: str, b: str, last: int, threshold: float = 0.5
) -> tuple[list[dict], list[str]]:
    """Value ``a`` of ``field`` against value ``b`` in every cell (values as written in group
    labels, e.g. ``max-critic``, ``4``, ``0.5``): the rows (:data:`COMPARE_COLUMNS`), one Holm
    family over all of them, and the cells left out for fewer than 2 runs on a side."""
    if not any(field in run.fields for run in runs):
        raise ConfigError(field, "not a config field of these runs (--compare)")
    names = [n for n in differing_fields([r.fields for r in runs]) if n != field]

    def cell_of(run: Run) -> str:
        parts = [] if field == "method" else [run.fields["method"]]
        parts += [f"{n}={format_value(run.fields[n])}" for n in names if n in run.fields]
        return " ".join(parts) or "all runs"

    sides: dict[str, dict[str, list[float]]] = defaultdict(lambda: {a: [], b: []})
    present, seen = set(), set()
    spellings = {a: {a, _as_label(a)}, b: {b, _as_label(b)}}
    for run, score in scored(runs, last)[0]:
        value = format_value(run.fields.get(field))
        present.add(value)
        for side, spelt in spellings.items():
            if value in spelt:
                sides[cell_of(run)][side].append(score)
                seen.add(side)
    for side in (a, b):
        if side not in seen:
            have = ", ".join(sorted(present - {"None"}))
            raise ConfigError("--compare", f"no run has {field} = {side} (they have: {have})")
    rows, skipped = [], []
    for cell, side in sides.items():
        if min(len(side[a]), len(side[b])) < 2:  # Welch's t and g need a spread on each side
            skipped.append(f"{cell}: {len(side[a])} run(s) with {field}={a}, {len(side[b])} "
                           f"with {field}={b}: not compared")  # fmt: skip
            continue
        rows.append({"cell": cell, "A": f"{field}={a}", "B": f"{field}={b}",
                     **compare_samples(side[a], side[b], threshold)})  # fmt: skip
    if not rows:
        raise ConfigError("--compare", f"no cell has 2 runs or more of both {field}={a} and "
                          f"{field}={b} (a field that changes with {field} puts them in "
                          "different cells: " + "; ".join(skipped) + ")")  # fmt: skip
    holm_families(rows, lambda row: "all")
    return [{k: row[k] for k in COMPARE_COLUMNS} for row in rows], skipped


def format_number(value) -> str:
    """A table's number: 3 significant digits, ``n/a`` for NaN; anything else as ``str``."""
    if isinstance(value, (float, np.floating)):
        return "n/a" if math.isnan(value) else f"{value:.3g}"
    return str(value)


SIGNIFICANCE_HEADER = (
    "mean A | mean B | p (perm.) | p (Holm, m) | Welch t (df) | Hedges' g | learn A | learn B"
)
"""The Markdown columns of :func:`significance_cells` (8 of them)."""


def significance_cells(r: dict) -> str:
    """A row's :func:`compare_samples` values (with ``p_holm`` and ``family_size``) as the
    Markdown cells under :data:`SIGNIFICANCE_HEADER`."""
    f = format_number
    welch = "n/a" if math.isnan(r["welch_t"]) else f"{r['welch_t']:.2f} ({r['welch_df']:.1f})"
    return (f"{r['mean_A']:.2f} | {r['mean_B']:.2f} | {f(r['p_permutation'])} | "
            f"{f(r['p_holm'])} ({r['family_size']}) | {welch} | {f(r['hedges_g'])} | "
            f"{r['learn_A']:.0%} | {r['learn_B']:.0%}")  # fmt: skip


def markdown_header(*lead: str) -> str:
    """The header and separator lines of a table: columns ``lead``, then
    :data:`SIGNIFICANCE_HEADER`."""
    return f"| {' | '.join(lead)} | {SIGNIFICANCE_HEADER} |\n|" + "---|" * (len(lead) + 8)


def cells_markdown(rows: list[dict], last: int) -> str:
    lines = [f"| group | n | final G (last {last}) +- 95% CI | range | learn |",
             "|---|---|---|---|---|"]  # fmt: skip
    for r in rows:
        ci = r["ci95_half_width"]
        ci = "n/a" if math.isnan(ci) else f"{ci:.2f}"
        lines.append(f"| {r['group']} | {r['n']} | {r['mean']:.2f} +- {ci} | "
                     f"{r['min']:.2f}-{r['max']:.2f} | {r['learned']:.0%} |")  # fmt: skip
    return "\n".join(lines) + "\n"


def comparisons_markdown(rows: list[dict]) -> str:
    lines = [markdown_header("cell", "A", "B", "n")]
    for r in rows:
        lines.append(f"| {r['cell']} | {r['A']} | {r['B']} | {r['n_A']}/{r['n_B']} | "
                     f"{significance_cells(r)} |")  # fmt: skip
    return "\n".join(lines) + "\n"


def write_csv(rows: list[dict], columns: list[str], path: Path) -> Path:
    """``rows`` as CSV with ``columns``; floats at full precision (``repr``)."""
    with open(path, "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=columns)
        writer.writeheader()
        for row in rows:
            writer.writerow({k: repr(v) if isinstance(v, float) else v for k, v in row.items()})
    return path
