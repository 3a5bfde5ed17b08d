"""Rows of the standing table set against the row each is read beside, at n_req 1-4.

    python experiments/standing_tests.py

Reads the committed runs.csv files only (no run directory): each row's final G per seed,
from the sweeps that made it. Tests, in each cell, the row against its reference with
:func:`physrover.analysis.tables.compare_samples` (two-sided exact permutation p over
the 10 against 10 seeds, Welch's t, Hedges' g), Holm's method within each pair's four
cells. The pairs were chosen after the runs, to say what the results' prose says in
numbers: the screen's winner against the paper's max critic, leniency against the
average of 10 episodes (both play 10 episodes a generation), the hall of fame against D
(its credit without the best team). Writes ``results/standing_tests.{csv,md}``.
"""

from __future__ import annotations

import csv
from pathlib import Path

from physrover.analysis import tables

OUT = Path(__file__).parent / "results"

# (row, its sweeps' runs.csv files, method): the reference's n_req 1-2 are
# standing-table-low's, 3-4 fig4-7-long's (pooled into results/runs.csv).
LOW_AND_LONG = ("standing-table-low/runs.csv", "runs.csv")
ROWS = {
    "max critic on D++, per-step targets": (("standing-table-winner/runs.csv",), "max-critic"),
    "max critic": (LOW_AND_LONG, "max-critic"),
    "leniency": (("standing-table-lenient/runs.csv",), "leniency"),
    "average of 10 episodes": (LOW_AND_LONG, "average"),
    "hall of fame": (("standing-table-lenient/runs.csv",), "hall-of-fame"),
    "D": (LOW_AND_LONG, "D"),
}
PAIRS = [("max critic on D++, per-step targets", "max critic"),
         ("leniency", "average of 10 episodes"), ("hall of fame", "D")]  # fmt: skip
SWEEPS = {"standing-table-low", "fig4-7-long", "standing-table-winner", "standing-table-lenient"}
N_REQ = (1, 2, 3, 4)


def scores(row: str, n_req: int) -> list[float]:
    """The row's final G at ``n_req``, one per seed (seed order)."""
    files, method = ROWS[row]
    found = []
    for name in files:
        with open(OUT / name, newline="") as f:
            found += [(int(r["seed"]), float(r["final_G"])) for r in csv.DictReader(f)
                      if r["sweep"] in SWEEPS and r["method"] == method
                      and int(r["n_req"]) == n_req and r.get("feedback", "D") == "D"]  # fmt: skip
    seeds = [seed for seed, _ in found]
    if len(set(seeds)) != len(seeds):
        raise SystemExit(f"{row}, n_req {n_req}: a seed appears twice in {files}")
    return [g for _, g in sorted(found)]


def main() -> None:
    rows = []
    for a, b in PAIRS:
        for n_req in N_REQ:
            row = tables.compare_samples(scores(a, n_req), scores(b, n_req))
            rows.append({"A": a, "B": b, "n_req": n_req, **row})
    tables.holm_families(rows, lambda r: r["A"])
    columns = ["A", "B", "n_req", *[k for k in rows[0] if k not in ("A", "B", "n_req")]]
    tables.write_csv(rows, columns, OUT / "standing_tests.csv")
    lines = [tables.markdown_header("A", "B", "n_req", "n")]
    lines += [f"| {r['A']} | {r['B']} | {r['n_req']} | {r['n_A']}/{r['n_B']} | "
              f"{tables.significance_cells(r)} |" for r in rows]  # fmt: skip
    (OUT / "standing_tests.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
