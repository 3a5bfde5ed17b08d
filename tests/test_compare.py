"""physrover compare: planned comparisons over a runs.csv, from a sweep file's
[[comparisons]] or a claims file (paper-claims), with no run directory needed. The committed
tables regenerate from the committed runs.csv byte for byte."""

import filecmp
from pathlib import Path

import pytest

from physrover.analysis.claim_tests import claim_comparisons, load_claims
from physrover.analysis.comparisons import compare_cells, planned_comparisons
from physrover.analysis.tables import compare_samples
from physrover.cli import main
from physrover.config import ConfigError

RESULTS = Path(__file__).parents[1] / "experiments" / "results"

STUDIES = ["mixed-team", "mixed-team-long", "mixed-team-long-nreq2", "trajectory-critics",
           "trajectory-critics-long", "curriculum-screen", "partial-credit-screen",
           "step-target-screen", "step-target-long"]  # fmt: skip
"""The committed studies whose sweep files plan comparisons (each has NAME_significance)."""


def _same(made: Path, committed: Path) -> None:
    assert filecmp.cmp(made, committed, shallow=False), f"{made} differs from {committed}"


def test_the_paper_claims_tables_regenerate_byte_for_byte(tmp_path, capsys):
    assert main(["compare", str(RESULTS / "runs.csv"), "paper-claims", "--out", str(tmp_path)]) == 0
    assert capsys.readouterr().out.splitlines() == [
        f"115 comparisons -> {tmp_path / 'paper-claims_significance.md'}",
        f"12 trends over rovers -> {tmp_path / 'paper-claims_trend.md'}",
    ]
    for name in ("significance", "trend"):
        for suffix in (".md", ".csv"):
            file = f"paper-claims_{name}{suffix}"
            _same(tmp_path / file, RESULTS / file)


@pytest.mark.parametrize("study", STUDIES)
def test_each_studys_comparisons_regenerate_from_its_sweep_file(tmp_path, study):
    runs = RESULTS / study / "runs.csv"
    assert main(["compare", str(runs), study, "--out", str(tmp_path)]) == 0
    for suffix in (".md", ".csv"):
        _same(
            tmp_path / f"{study}_significance{suffix}",
            RESULTS / study / f"{study}_significance{suffix}",
        )


def _rows(*runs) -> list[dict]:
    """Rows of a runs.csv: (method, n_req, feedback, final_G) per run."""
    return [
        {"method": m, "n_req": str(n), "feedback": fb, "final_G": str(g)} for m, n, fb, g in runs
    ]


RUNS = _rows(
    *[("D", n, "D", g + n) for n in (1, 2, 3) for g in (0.0, 0.5, 1.0)],
    *[("G", n, "D", g + n + 2) for n in (1, 2, 3) for g in (0.0, 0.25, 1.0)],
    *[("D", n, "ID", g + n + 1) for n in (1, 2, 3) for g in (0.0, 0.5)],
)
DEFAULTS = {"method": "D", "n_req": "1", "feedback": "D"}


def test_cells_of_where_in_its_order_and_no_others():
    comparison = {"a": {"method": "G"}, "b": {"method": "D"}, "where": {"n_req": [3, 1]}}
    rows, skipped = compare_cells(RUNS, [comparison], DEFAULTS, ["method", "n_req", "feedback"])
    # feedback, which where leaves out, takes each value the runs have (G has no ID runs)
    assert [r["cell"] for r in rows] == ["n_req=3 feedback=D", "n_req=1 feedback=D"]
    assert [s.split(", ")[1].split(":")[0] for s in skipped] == [
        "n_req=3 feedback=ID", "n_req=1 feedback=ID"
    ]  # fmt: skip
    # the plain loop: G's and D's (feedback D) finals at n_req 3
    g = [float(r["final_G"]) for r in RUNS if r["method"] == "G" and r["n_req"] == "3"]
    d = [float(r["final_G"]) for r in RUNS if r["method"] == "D" and r["n_req"] == "3"
         and r["feedback"] == "D"]  # fmt: skip
    assert rows[0]["mean_A"] == pytest.approx(sum(g) / 3) and len(d) == 3
    assert rows[0]["p_permutation"] == compare_samples(g, d)["p_permutation"]


def test_a_field_one_side_names_takes_the_base_value_on_the_other():
    # feedback = "ID" on A only: B keeps the base's D (not D on ID, nor every feedback)
    comparison = {"a": {"method": "D", "feedback": "ID"}, "b": {"method": "D"}}
    rows, _ = planned_comparisons(RUNS, [comparison], DEFAULTS, ["method", "n_req", "feedback"])
    assert [(r["cell"], r["n_A"], r["n_B"]) for r in rows] == [
        ("n_req=1", 2, 3), ("n_req=2", 2, 3), ("n_req=3", 2, 3)
    ]  # fmt: skip
    assert [r["family_size"] for r in rows] == [3, 3, 3]  # Holm over all


def test_a_field_the_base_lacks_does_not_filter_the_other_side():
    # a setting of A's method's own table (the base has none): B is not filtered on it
    runs = [{**r, "trajectory_loss": "rank" if r["method"] == "G" else ""} for r in RUNS]
    comparison = {"a": {"method": "G", "trajectory_loss": "rank"}, "b": {"method": "D"}}
    rows, _ = planned_comparisons(runs, [comparison], DEFAULTS, ["method", "n_req", "feedback"])
    assert [(r["cell"], r["n_A"], r["n_B"]) for r in rows] == [
        (f"n_req={n} feedback=D", 3, 3) for n in (1, 2, 3)
    ]  # fmt: skip


def test_a_cell_field_some_runs_lack_does_not_filter_them():
    # hybrid-screen: hybrid.period is a cell field (1 or 5 among the hybrid runs); G's runs
    # without a hybrid lack it and are compared in its cell, not left in one of their own
    runs = [{**r, "period": ""} for r in RUNS if r["method"] == "D" and r["feedback"] == "D"]
    runs += [{**r, "period": "1"} for r in RUNS if r["method"] == "G"]
    runs += [{**r, "method": "G", "period": "5"} for r in runs[:1]]  # one G run at period 5
    comparison = {"a": {"method": "G"}, "b": {"method": "D"}}
    rows, skipped = planned_comparisons(runs, [comparison], DEFAULTS, ["n_req", "period"])
    assert [(r["cell"], r["n_A"], r["n_B"]) for r in rows] == [
        (f"n_req={n} period=1", 3, 3) for n in (1, 2, 3)
    ]  # fmt: skip
    # period 5 is a cell of its own for the runs that have it (1 against 3: not compared)
    assert len(skipped) == 1 and "n_req=1 period=5: 1 and 3 runs" in skipped[0]


def test_a_claims_side_is_pinned_to_the_defaults_it_leaves_out():
    doc = {"defaults": {"feedback": "D", "motion": "ideal", "variant": ""},
           "labels": {"n_rovers": "rovers"}, "grid": ["n_req", "n_rovers"],
           "comparisons": [{"claim": 1, "a": {"sweep": "s", "method": "G"},
                            "b": {"sweep": "s", "method": "D"},
                            "where": {"n_req": [2], "n_rovers": [15]}}]}  # fmt: skip
    rows = [{**r, "sweep": "s", "n_rovers": "15", "motion": "ideal", "variant": ""} for r in RUNS]
    rows.append({**rows[0], "motion": "physics", "final_G": "100"})  # not an idealised D run
    rows.append({**rows[0], "n_req": "2", "motion": "physics", "final_G": "100"})
    (row,) = claim_comparisons(rows, doc)
    assert (row["A"], row["B"], row["n"]) == ("G n_req=2 rovers=15", "D n_req=2 rovers=15", "3/3")
    assert row["mean_B"] == pytest.approx(2.5)


def test_claims_file_errors_are_one_line(tmp_path, capsys):
    bad = tmp_path / "bad.toml"
    bad.write_text('[[comparisons]]\na = { method = "G" }\nb = { method = "D" }\n')
    with pytest.raises(ConfigError, match=r"comparisons\[0\]: needs claim, a and b"):
        load_claims(bad)
    bad.write_text("[claimz]\n")
    with pytest.raises(ConfigError, match="claims.claimz: unknown table"):
        load_claims(bad)
    runs = tmp_path / "runs.csv"
    runs.write_text("sweep,method,n_req,seed,final_G\ns,D,1,0,1.0\n")
    assert main(["compare", str(tmp_path / "none.csv"), "paper-claims"]) == 2
    assert main(["compare", str(runs), "paper-claims", "--out", str(tmp_path / "o")]) == 2
    assert main(["compare", str(runs), "mixed-team"]) == 2
    assert main(["compare", str(runs), str(tmp_path / "nowhere.toml")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err[:3] == [
        f"physrover: error: {tmp_path / 'none.csv'}: no such file (a runs.csv of physrover "
        "results)",
        "physrover: error: claims: paper-claims: no comparison or trend has 2 runs a side",
        "physrover: error: the runs.csv has no row of sweep mixed-team",
    ]
    assert err[3].startswith(f"physrover: error: {tmp_path / 'nowhere.toml'}: no such sweep file")
    assert not (tmp_path / "o").exists()  # nothing written
