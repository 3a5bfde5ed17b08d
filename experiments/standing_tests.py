"""Rows of the standing table set against the row each is read beside.

    python experiments/standing_tests.py

From the committed runs.csv files only, each row's final G per seed against its
reference's in each cell (:func:`physrover.analysis.tables.compare_samples`: exact
permutation p, Welch's t, Hedges' g), Holm within each pair's cells. The pairs, chosen
after the runs: at n_req 1-4 the screen's winner against the max critic, leniency against
the average of 10 episodes (both play 10 a generation), the hall of fame against D; at
n_req 5-6 MAPPO under the coupling curriculum against the max critic. Writes
``results/standing_tests.{csv,md}``."""

from __future__ import annotations

import csv
from pathlib import Path

from physrover.analysis import tables

OUT = Path(__file__).parent / "results"

# (row, its sweeps' runs.csv files, method): the reference's n_req 1-2 are
# standing-table-low's, 3-6 fig4-7-long's (pooled into results/runs.csv).
LOW_AND_LONG = ("standing-table-low/runs.csv", "runs.csv")
ROWS = {
    "max critic on D++, per-step targets": (("standing-table-winner/runs.csv",), "max-critic"),
    "max critic": (LOW_AND_LONG, "max-critic"),
    "leniency": (("standing-table-lenient/runs.csv",), "leniency"),
    "average of 10 episodes": (LOW_AND_LONG, "average"),
    "hall of fame": (("standing-table-lenient/runs.csv",), "hall-of-fame"),
    "D": (LOW_AND_LONG, "D"),
    "MAPPO, std 2.72, coupling curriculum": (("mappo-curriculum-screen/runs.csv",), "mappo"),
}
LOW = (1, 2, 3, 4)
PAIRS = [("max critic on D++, per-step targets", "max critic", LOW),
         ("leniency", "average of 10 episodes", LOW), ("hall of fame", "D", LOW),
         ("MAPPO, std 2.72, coupling curriculum", "max critic", (5, 6))]  # fmt: skip
SWEEPS = {"standing-table-low", "fig4-7-long", "standing-table-winner", "standing-table-lenient",
          "mappo-curriculum-screen"}  # fmt: skip


def scores(row: str, n_req: int) -> list[float]:
    """The row's final G at ``n_req``, one per seed (seed order)."""
    files, method = ROWS[row]
    found = []
    for name in files:
        with open(OUT / name, newline="") as f:
            found += [(int(r["seed"]), float(r["final_G"])) for r in csv.DictReader(f)
                      if r["sweep"] in SWEEPS and r["method"] == method
                      and int(r["n_req"]) == n_req and r.get("feedback", "D") == "D"]  # fmt: skip
    if len({seed for seed, _ in found}) != len(found):
        raise SystemExit(f"{row}, n_req {n_req}: a seed appears twice in {files}")
    return [g for _, g in sorted(found)]


def main() -> None:
    rows = []
    for a, b, couplings in PAIRS:
        for n_req in couplings:
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
