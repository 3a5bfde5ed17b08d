"""physrover table: final scores per group and two settings compared, against hand-worked
values on run directories whose final scores are chosen here."""

import csv

import pytest

from physrover.analysis.tables import compare_samples, parse_compare
from physrover.cli.main import main
from physrover.config import ConfigError, RunConfig
from physrover.learn.stats import stats_header

# Final scores (mean eval G of the last 2 generations) by (method, n_req), one per seed.
FINALS = {
    ("max-critic", 4): [5.0, 6.0, 7.0],
    ("D", 4): [0.0, 0.0, 0.1],
    ("max-critic", 6): [0.0, 1.0, 2.0],
    ("D", 6): [0.0, 0.0, 1.0],
}


def _runs(root, finals=FINALS):
    for (method, n_req), scores in finals.items():
        for seed, score in enumerate(scores):
            run = root / f"{method}_{n_req}_{seed}"
            run.mkdir(parents=True)
            config = RunConfig().with_overrides(
                {"method": method, "n_req": n_req, "seed": seed, "generations": 3}
            )
            (run / "config.toml").write_text(config.to_toml())
            rows = [[g, eval_G, 0.0, 0.0, "nan", 1.0] for g, eval_G in
                    [(1, 9.0), (2, score - 0.5), (3, score + 0.5)]]  # fmt: skip
            with open(run / "metrics.csv", "w", newline="") as f:
                csv.writer(f).writerows([stats_header(), *rows])
    return root


def _read(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def test_compare_samples_by_hand():
    r = compare_samples([1.0, 2.0, 3.0], [4.0, 5.0, 6.0])
    assert (r["n_A"], r["n_B"], r["mean_A"], r["mean_B"], r["diff"]) == (3, 3, 2.0, 5.0, -3.0)
    assert r["p_permutation"] == pytest.approx(2 / 20)  # only the observed split and its mirror
    assert r["welch_t"] == pytest.approx(-3 / (2 / 3) ** 0.5)  # variances 1 and 1
    assert r["welch_df"] == pytest.approx(4.0)
    assert r["hedges_g"] == pytest.approx(-3 * (1 - 3 / 15))  # pooled sd 1, J = 1 - 3/(4*6-9)
    assert (r["learn_A"], r["learn_B"]) == (1.0, 1.0)


def test_table_cells_and_comparisons_by_hand(tmp_path, capsys):
    root = _runs(tmp_path / "runs")
    prefix = tmp_path / "out" / "t"
    argv = ["table", str(root), "--last", "2", "--compare", "method=max-critic,D",
            "--out", str(prefix)]  # fmt: skip
    assert main(argv) == 0
    printed = capsys.readouterr().out
    assert "| max-critic n_req=4 | 3 | 6.00 +- 2.48 | 5.00-7.00 | 100% |" in printed
    cells = {r["group"]: r for r in _read(f"{prefix}_cells.csv")}
    assert sorted(cells) == ["D n_req=4", "D n_req=6", "max-critic n_req=4", "max-critic n_req=6"]
    assert float(cells["max-critic n_req=4"]["mean"]) == pytest.approx(6.0)
    # t_{0.975, 2} = 4.303 (stats' table, 3 decimals), sd 1, n 3
    assert float(cells["max-critic n_req=4"]["ci95_half_width"]) == pytest.approx(4.303 / 3**0.5)
    assert float(cells["D n_req=4"]["learned"]) == 0.0  # 0.1 is not above 0.5
    assert float(cells["D n_req=6"]["learned"]) == pytest.approx(1 / 3)
    pairs = {r["cell"]: r for r in _read(f"{prefix}_compare.csv")}
    assert sorted(pairs) == ["n_req=4", "n_req=6"]
    # n_req 4: the samples separate, p = 2/20. n_req 6: pooled {0,0,0,1,1,2}, observed
    # difference 2/3; of the 20 splits, 7 have sum <= 1 and 7 sum >= 3: p = 14/20.
    assert float(pairs["n_req=4"]["p_permutation"]) == pytest.approx(0.1)
    assert float(pairs["n_req=6"]["p_permutation"]) == pytest.approx(0.7)
    # Holm over m = 2: 2 x 0.1 = 0.2, then max(0.2, 1 x 0.7) = 0.7.
    assert float(pairs["n_req=4"]["p_holm"]) == pytest.approx(0.2)
    assert float(pairs["n_req=6"]["p_holm"]) == pytest.approx(0.7)
    assert {r["family_size"] for r in pairs.values()} == {"2"}
    assert (prefix.parent / "t_compare.md").read_text().startswith("| cell | A | B |")


def test_compare_another_field_within_each_method(tmp_path, capsys):
    root = _runs(tmp_path / "runs")
    assert main(["table", str(root), "--last", "2", "--compare", "n_req=4,6"]) == 0
    printed = capsys.readouterr().out
    assert "| max-critic | n_req=4 | n_req=6 | 3/3 | 6.00 | 1.00 |" in printed
    assert "| D | n_req=4 | n_req=6 | 3/3 | 0.03 | 0.33 |" in printed


def test_cells_without_two_runs_a_side_are_named_not_compared(tmp_path, capsys):
    root = _runs(tmp_path / "runs", {**FINALS, ("D", 6): [0.0]})
    assert main(["table", str(root), "--last", "2", "--compare", "method=max-critic,D"]) == 0
    captured = capsys.readouterr()
    assert "n_req=6: 3 run(s) with method=max-critic, 1 with method=D: not compared" in (
        captured.err
    )
    assert "| n_req=4 |" in captured.out and "| n_req=6 |" not in captured.out
    assert "| D n_req=6 | 1 | 0.00 +- n/a | 0.00-0.00 | 0% |" in captured.out


def test_a_group_of_runs_of_different_lengths_is_named(tmp_path, capsys):
    root = _runs(tmp_path / "runs")
    metrics = root / "D_4_2" / "metrics.csv"  # as if still running: 2 of its 3 generations
    metrics.write_text("".join(metrics.read_text().splitlines(keepends=True)[:3]))
    assert main(["table", str(root), "--last", "2"]) == 0
    assert "D n_req=4: runs of 2 to 3 generations" in capsys.readouterr().err


def test_values_are_read_as_labels_and_unscored_runs_left_out(tmp_path, capsys):
    root = _runs(tmp_path / "runs")
    empty = root / "D_4_2" / "metrics.csv"  # started, no generation yet
    empty.write_text(empty.read_text().splitlines(keepends=True)[0])
    assert main(["table", str(root), "--last", "2", "--compare", "n_req=4.0,6"]) == 0
    captured = capsys.readouterr()
    assert "D_4_2: no generations yet, left out" in captured.err
    assert "| D | n_req=4.0 | n_req=6 | 2/3 | 0.00 | 0.33 |" in captured.out  # as asked
    assert parse_compare(" critic_lr = 5E-6 , 0.50 ") == ("critic_lr", "5E-6", "0.50")
    with pytest.raises(ValueError, match="finite"):
        compare_samples([1.0, float("nan")], [1.0, 2.0])


def test_a_comparison_no_cell_can_make_is_an_error(tmp_path, capsys):
    root = _runs(tmp_path / "runs", {("max-critic", 4): [1.0, 2.0], ("D", 6): [0.0, 1.0]})
    assert main(["table", str(root), "--compare", "method=max-critic,D"]) == 2
    assert "no cell has 2 runs or more of both" in capsys.readouterr().err


def test_bad_comparisons_are_one_line(tmp_path, capsys):
    root = _runs(tmp_path / "runs")
    for spec in ("method=max-critic", "method", "=a,b", "method=a,b,c"):
        with pytest.raises(ConfigError, match="expected FIELD=A,B"):
            parse_compare(spec)
    assert main(["table", str(root), "--compare", "method=max-critic,mean-critic"]) == 2
    assert "no run has method = mean-critic (they have: D, max-critic)" in capsys.readouterr().err
    assert main(["table", str(root), "--compare", "n_reqq=4,6"]) == 2
    assert "n_reqq: not a config field" in capsys.readouterr().err
    assert main(["table", str(root), "--last", "0"]) == 2
