"""Issue 33's study: does influence credit or the fitness critic carry the coupling between
agent classes? (``physrover/sweeps/mixed-team.toml``)

    physrover results SWEEP_DIR --out experiments/results/mixed-team   # runs.csv first
    python experiments/mixed_team.py experiments/results/mixed-team/runs.csv
    python experiments/mixed_team.py --follow-up experiments/results/mixed-team-long/runs.csv

Reads runs.csv (a row per finished run; its final score is the mean eval G of the last 50
generations) and writes ``significance.md`` and ``significance.csv`` beside it: the four
planned comparisons at each n_req, A against B on the same seeds (means, the exact
two-sided permutation p-value, that p adjusted by Holm's method over the study's eight
comparisons as one family, Welch's t, Hedges' g, the fraction of seeds that learn):

- ID-step vs D: does crediting a UAV with the captures it enabled beat D, which gives a
  UAV 0 whatever it does?
- ID-step vs G: ... and the team score, which credits every agent with everything?
- max-critic[G] vs G: does a critic of each agent's own (class's) observations, trained
  on G, sharpen G?
- max-critic[G] vs ID-step: the critic against influence credit.

``--follow-up`` (``physrover/sweeps/mixed-team-long.toml``, n_req 1 at 5000 generations):
the three comparisons of the variants that led after 2000 generations, Holm over three:
max-critic[G] vs G, max-critic[G] vs ID, ID vs G.
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

COMPARISONS = [
    ("D [ID-step]", "D"),
    ("D [ID-step]", "G"),
    ("max-critic [G]", "G"),
    ("max-critic [G]", "D [ID-step]"),
]
"""(A, B) variant names: the method, with its feedback where it is not D."""

FOLLOW_UP = [
    ("max-critic [G]", "G"),
    ("max-critic [G]", "D [ID]"),
    ("D [ID]", "G"),
]
"""The follow-up's (A, B): the variants that led at n_req 1 after 2000 generations."""


def variant(row: dict) -> str:
    feedback = row.get("feedback") or "D"
    return row["method"] if feedback == "D" else f"{row['method']} [{feedback}]"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("runs", type=Path, help="runs.csv of physrover results")
    parser.add_argument("--follow-up", action="store_true",
                        help="the follow-up's comparisons (mixed-team-long)")  # fmt: skip
    args = parser.parse_args()
    scores = final_scores(args.runs, variant)  # (variant, n_req) -> {seed: final}
    comparisons = []
    for n_req in sorted({n for _, n in scores}, key=lambda n: int(n or 0)):
        for a, b in FOLLOW_UP if args.follow_up else COMPARISONS:
            first, second = scores.get((a, n_req), {}), scores.get((b, n_req), {})
            seeds = sorted(set(first) & set(second), key=int)
            if seeds:
                comparisons.append({"A": a, "B": b, "n_req": n_req, **compare_samples(
                    [first[s] for s in seeds], [second[s] for s in seeds])})  # fmt: skip
    if not comparisons:
        raise SystemExit(f"{args.runs}: no cell of the study has finished runs")
    holm_families(comparisons, lambda row: "all")
    lead = {k: k for k in ("A", "B", "n_req") if any(row[k] for row in comparisons)}
    print(write_significance(comparisons, args.runs.parent, lead), end="")


if __name__ == "__main__":
    main()
