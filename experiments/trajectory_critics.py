"""Issue 34's tables: each trajectory critic against the paper's max critic, per coupling.

    physrover results SWEEP_DIR --out experiments/results/NAME   # runs.csv first
    python experiments/trajectory_critics.py experiments/results/NAME/runs.csv

Reads runs.csv (a row per finished run, its final score = mean eval G of the last 50
generations) and writes ``significance.md`` and ``significance.csv`` beside it: for every
variant (method and trajectory_loss) and n_req, the variant (A) against the max critic (B)
on the same seeds: means, the exact two-sided permutation p-value, that p adjusted by
Holm's method over all the sweep's comparisons (one family: the screen asks one question
of every variant), Welch's t, Hedges' g and the fraction of seeds that learn at all.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from physrover.analysis.tables import (
    compare_samples,
    final_scores,
    holm_families,
    write_significance,
)

BASELINE = "max-critic"


def variant(row: dict) -> str:
    loss = row.get("trajectory_loss", "")
    return row["method"] + (f" [{loss}]" if loss and row["method"] != BASELINE else "")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("runs", type=Path, help="runs.csv of physrover results")
    args = parser.parse_args()
    scores = final_scores(args.runs, variant)  # (variant, n_req) -> {seed: final}
    comparisons = []
    for (name, n_req), finals in sorted(scores.items()):
        base = scores.get((BASELINE, n_req), {})
        seeds = sorted(set(finals) & set(base), key=int)
        if name == BASELINE or not seeds:
            continue
        comparisons.append({"variant": name, "n_req": n_req, **compare_samples(
            [finals[s] for s in seeds], [base[s] for s in seeds])})  # fmt: skip
    holm_families(comparisons, lambda row: "all")
    lead = {"variant (A) vs max critic (B)": "variant", "n_req": "n_req"}
    print(write_significance(comparisons, args.runs.parent, lead), end="")


if __name__ == "__main__":
    main()
