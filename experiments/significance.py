"""Tests of significance for the claims of the paper's Section 5 that RESULTS.md checks.

    python experiments/significance.py [--runs experiments/results/runs.csv]

Reads each run's final score (mean eval G of its last 50 generations) from ``runs.csv`` and
writes ``significance.csv`` and ``significance.md`` beside it: for every comparison of two
cells, the means, the difference, the exact two-sided permutation p-value (every split of
the seeds; no normality assumed), that p-value adjusted by Holm's method within its family
(the comparisons one claim makes in one sweep, their number m beside it), Welch's t and its
degrees of freedom, Hedges' g, and the fraction of seeds that learn at all (final score
above 0.5) in each cell. Also ``trend.csv`` and ``trend.md``: for Figs 8-9, whether a
method's score rises with the team size (Spearman's rho of the seeds' final scores with
the number of rovers, its permutation p-value and that p adjusted by Holm's method over
the sweep's trends).
"""

from __future__ import annotations

import argparse
import csv
from collections import defaultdict
from pathlib import Path

import numpy as np

from physrover.analysis.tables import (
    compare_samples,
    format_number,
    holm_families,
    markdown_header,
    significance_cells,
)
from physrover.core.stats import spearman_trend

# (claim, sweep, cell A, cell B); a cell is (method, n_req, n_rovers), or (sweep, method,
# n_req, n_rovers) for a cell of another sweep; a method run as a variant (runs.csv's
# ``variant`` column) is named ``METHOD [VARIANT]``.
ENSEMBLE = ("stronger-critic-ensemble", "ablation-output-weights")  # the same code, 0.2.0
PAPER_CRITIC = "max-critic [critic_output_weights=fixed]"
COMPARISONS = [
    *[(1, "fig4-7-long", ("average", 3, 15), (m, 3, 15)) for m in ("max-critic", "D")],
    *[(3, "fig4-7-long", ("average", n, 15), ("D", n, 15)) for n in (4, 5)],
    *[(4, "fig4-7-long", ("max-critic", n, 15), ("mean-critic", n, 15)) for n in (3, 4, 5, 6)],
    *[(4, "fig4-7", ("max-critic", n, 15), ("mean-critic", n, 15)) for n in (3, 4, 5, 6)],
    *[(4, "fig4-7-long", ("mean-critic", n, 15), ("average", n, 15)) for n in (5, 6)],
    (4, "fig4-7-long", ("average", 4, 15), ("max-critic", 4, 15)),
    *[
        (5, sweep, (m, n, r), ("average", n, r))
        for sweep, methods in (
            ("fig8-9-long", ("max-critic",)),
            ("fig8-9-paper", ("max-critic", "mean-critic")),
        )
        for m in methods
        for n in (4, 6)
        for r in (6, 9, 12, 15)
    ],  # fmt: skip
    *[
        (4, "fig8-9-paper", ("max-critic", n, r), ("mean-critic", n, r))
        for n in (4, 6)
        for r in (6, 9, 12, 15)
    ],
    # issue 13, experiment 2: the same claims on random POI layouts (2000 generations)
    *[(1, "ring-random", ("average", 3, 15), (m, 3, 15)) for m in ("max-critic", "D")],
    *[(3, "ring-random", ("average", n, 15), ("D", n, 15)) for n in (4, 5)],
    *[(4, "ring-random", ("max-critic", n, 15), ("mean-critic", n, 15)) for n in (3, 4, 5, 6)],
    *[
        (4, "ring-random", (m, n, 15), ("average", n, 15))
        for m in ("max-critic", "mean-critic")
        for n in (5, 6)
    ],  # fmt: skip
    (4, "ring-random", ("average", 4, 15), ("max-critic", 4, 15)),
    # issue 13, experiment 1 (D++ as the feedback)
    *[(6, "dpp", ("D on D++", n, 15), ("D", n, 15)) for n in (4, 5, 6)],
    *[(7, "dpp", ("max-critic on D++", n, 15), ("max-critic", n, 15)) for n in (4, 5, 6)],
    *[(7, "dpp", ("max-critic", n, 15), ("D on D++", n, 15)) for n in (4, 5, 6)],
    # issue 16: the optimistic ensemble and trained output weights vs the paper's max critic
    *[
        (
            8,
            ENSEMBLE[0],
            (f"max-critic [critic_ensemble=5 critic_optimism={b}]", n, 15),
            (ENSEMBLE[1], PAPER_CRITIC, n, 15),
        )
        for b in (0.0, 1.0)
        for n in (5, 6)
    ],  # fmt: skip
    *[
        (
            9,
            ENSEMBLE[1],
            ("max-critic [critic_output_weights=trained]", n, 15),
            (PAPER_CRITIC, n, 15),
        )
        for n in (5, 6)
    ],  # fmt: skip
    # issue 14: physical motion against the idealised twins (same seeds), and whether the
    # max critic's lead over D survives it
    *[
        (10, "physics-long", (f"{m} ({model})", n, 15), (m, n, 15))
        for m in ("D", "max-critic")
        for model in ("physics", "physics+collisions")
        for n in (3, 4, 5, 6)
    ],  # fmt: skip
    # the mean critic under physics, a later sweep of its own, against fig4-7-long's
    # idealised mean critic (10 seeds, physrover 0.1.0: the same training, other draws)
    *[
        (
            10,
            "physics-long-mean",
            (f"mean-critic ({model})", n, 15),
            ("fig4-7-long", "mean-critic", n, 15),
        )
        for model in ("physics", "physics+collisions")
        for n in (3, 4, 5, 6)
    ],  # fmt: skip
    *[
        (11, "physics-long", (f"max-critic ({model})", n, 15), (f"D ({model})", n, 15))
        for model in ("physics", "physics+collisions")
        for n in (3, 4, 5, 6)
    ],  # fmt: skip
    *[
        (
            12,
            "physics-long",
            (f"max-critic ({model})", n, 15),
            ("physics-long-mean", f"mean-critic ({model})", n, 15),
        )
        for model in ("physics", "physics+collisions")
        for n in (3, 4, 5, 6)
    ],  # fmt: skip
]

TEAM_SIZES = (6, 9, 12, 15)
TRENDS = [
    (sweep, method, n_req)
    for sweep in ("fig8-9-long", "fig8-9-paper")
    for method in ("average", "mean-critic", "max-critic")
    for n_req in (4, 6)
]
"""Claim 5's "scores rise with the number of rovers": (sweep, method, n_req) whose final
scores are tested for a trend over :data:`TEAM_SIZES` (a family per sweep)."""

MIN_SEEDS = 2
"""Comparisons of cells with fewer seeds a side are left out: one seed against one has no
variance to test against (Welch's t is undefined, every permutation p is 1)."""

CLAIMS = {
    1: "all methods learn at n_req 3",
    3: "the average improves on D at n_req 4-5",
    4: "critics learn everywhere; max critic above mean critic",
    5: "critics comparable or better than the average at every team size",
    6: "(beyond the paper) D++ rescues D under tight coupling",
    7: "(beyond the paper) D++ and the max critic: which helps, and do they combine",
    8: "(beyond the paper) an ensemble of critics, plain or optimistic, vs the paper's critic",
    9: "(ablation) trained hidden-to-output weights vs the paper's fixed ones",
    10: "(issue 14) physical motion, without and with collisions, vs idealised (same seeds; "
    "the mean critic: against fig4-7-long's ten seeds)",
    11: "(issue 14) the max critic vs D under physical motion",
    12: "(issue 14) the max critic vs the mean critic under physical motion",
}


def load(path: Path) -> dict[tuple, list[float]]:
    """{(sweep, method, n_req, n_rovers): [final score of each seed]}; a method run on
    another feedback than D is named ``METHOD on FEEDBACK``, under physical motion ``METHOD
    (physics)`` or ``METHOD (physics+collisions)``."""
    cells: dict[tuple, list[float]] = defaultdict(list)
    with open(path, newline="") as f:
        for row in csv.DictReader(f):
            method = row["method"]
            if row["motion"] != "ideal":
                method = f"{method} ({row['motion']})"
            if row.get("feedback", "D") not in ("", "D"):  # e.g. "D on D++"
                method = f"{method} on {row['feedback']}"
            if row.get("variant"):
                method = f"{method} [{row['variant']}]"
            key = (row["sweep"], method, int(row["n_req"]), int(row["n_rovers"]))
            cells[key].append(float(row["final_G"]))
    return cells


def compare(cells: dict) -> list[dict]:
    rows = []
    for claim, sweep, a, b in COMPARISONS:
        sweep_b = b[0] if len(b) == 4 else sweep
        b = b[1:] if len(b) == 4 else b
        x, y = cells.get((sweep, *a)), cells.get((sweep_b, *b))
        if not x or not y or min(len(x), len(y)) < MIN_SEEDS:  # e.g. a sweep still in chunks
            continue
        r = compare_samples(x, y)
        rows.append(
            {
                "claim": claim,
                "sweep": sweep if sweep_b == sweep else f"{sweep} vs {sweep_b}",
                "A": f"{a[0]} n_req={a[1]} rovers={a[2]}",
                "B": f"{b[0]} n_req={b[1]} rovers={b[2]}",
                "n": f"{len(x)}/{len(y)}",
                **{k: r[k] for k in ("mean_A", "mean_B", "diff", "p_permutation")},
                "p_holm": np.nan,  # adjusted below, once the claim's family is known
                "family_size": 0,
                **{k: r[k] for k in ("welch_t", "welch_df", "hedges_g", "learn_A", "learn_B")},
            }
        )
    # A claim's comparisons in one sweep: one family.
    holm_families(rows, lambda row: (row["claim"], row["sweep"]))
    return rows


def trends(cells: dict) -> list[dict]:
    """A row per :data:`TRENDS` entry whose every team size has :data:`MIN_SEEDS` seeds:
    the mean final score per size, Spearman's rho of the scores with the size and its
    permutation p (exact up to 8 scores, else 100,000 orderings seeded 0: smallest p
    1e-5), Holm-adjusted within the sweep (a method without spread, rho n/a and p 1,
    counts in its family)."""
    rows = []
    for sweep, method, n_req in TRENDS:
        samples = [cells.get((sweep, method, n_req, size), []) for size in TEAM_SIZES]
        if min(len(s) for s in samples) < MIN_SEEDS:
            continue
        by_size = list(zip(TEAM_SIZES, samples, strict=True))
        sizes = np.concatenate([[size] * len(s) for size, s in by_size])
        rho, p = spearman_trend(sizes, np.concatenate(samples))
        rows.append(
            {
                "claim": 5,
                "sweep": sweep,
                "method": method,
                "n_req": n_req,
                "n": "/".join(str(len(s)) for s in samples),
                **{f"mean_{size}": float(np.mean(s)) for size, s in by_size},
                "rho": rho,
                "p_permutation": p,
                "p_holm": np.nan,
                "family_size": 0,
            }
        )
    holm_families(rows, lambda row: row["sweep"])
    return rows


def _write_csv(rows: list[dict], path: Path) -> None:
    """``rows`` as CSV, their numbers as the tables print them (:func:`format_number`)."""
    with open(path, "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows({k: format_number(v) for k, v in r.items()} for r in rows)


def write_trends(rows: list[dict], out: Path) -> None:
    _write_csv(rows, out.with_suffix(".csv"))
    means = " | ".join(f"mean, {size} rovers" for size in TEAM_SIZES)
    lines = [
        f"| sweep | method | n_req | seeds | {means} | Spearman rho | p (perm.) | p (Holm, m) |",
        "|" + "---|" * (7 + len(TEAM_SIZES)),
    ]
    for r in rows:
        cells = " | ".join(f"{r[f'mean_{size}']:.2f}" for size in TEAM_SIZES)
        lines.append(
            f"| {r['sweep']} | {r['method']} | {r['n_req']} | {r['n']} | {cells} | "
            f"{format_number(r['rho'])} | {format_number(r['p_permutation'])} | "
            f"{format_number(r['p_holm'])} ({r['family_size']}) |"
        )
    out.with_suffix(".md").write_text("\n".join(lines) + "\n")


def write(rows: list[dict], out: Path) -> None:
    _write_csv(rows, out.with_suffix(".csv"))
    lines = [markdown_header("claim", "sweep", "A", "B", "n")]
    for r in rows:
        lead = f"| {r['claim']} | {r['sweep']} | {r['A']} | {r['B']} | {r['n']} |"
        lines.append(f"{lead} {significance_cells(r)} |")
    out.with_suffix(".md").write_text("\n".join(lines) + "\n")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    here = Path(__file__).parent / "results"
    parser.add_argument("--runs", type=Path, default=here / "runs.csv")
    args = parser.parse_args()
    cells = load(args.runs)
    rows = compare(cells)
    write(rows, args.runs.with_name("significance"))
    print(f"{len(rows)} comparisons -> {args.runs.with_name('significance.md')}")
    rows = trends(cells)
    if rows:
        write_trends(rows, args.runs.with_name("trend"))
        print(f"{len(rows)} trends over team size -> {args.runs.with_name('trend.md')}")


if __name__ == "__main__":
    main()
