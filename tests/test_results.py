"""physrover results: a sweep's runs.csv, cells and figures, rebuilt from its run
directories, pooling the rows of earlier machines (a sweep run in chunks of seeds)."""

import csv
import math

import pytest
from test_make_results import SWEEP, _fake_runs

from physrover.cli import main
from physrover.core.stats import t975
from physrover.experiment.sweep import Sweep


@pytest.fixture
def sweep(tmp_path):
    path = tmp_path / "sweep.toml"
    path.write_text(SWEEP.replace('"fig8-9-paper"', '"grid"'))
    return Sweep.load(path)


def _rows(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def _results(root, out, capsys=None):
    assert main(["results", str(root / "grid"), "--out", str(out)]) == 0


def test_runs_cells_and_figures_of_a_sweep(tmp_path, sweep, capsys):
    _fake_runs(sweep, tmp_path / "root", None)  # 2 methods x 2 team sizes x 4 seeds
    _results(tmp_path / "root", tmp_path / "out")
    rows = _rows(tmp_path / "out" / "runs.csv")
    assert len(rows) == 16
    assert list(rows[0])[:5] == ["sweep", "run", "method", "n_rovers", "seed"]
    # a run's final score is seed + n_rovers / 10 (+ 5 for the max critic): test_make_results
    for row in rows:
        expected = int(row["seed"]) + int(row["n_rovers"]) / 10 + 5 * (row["method"] != "D")
        assert float(row["final_G"]) == pytest.approx(expected)
        assert row["generations"] == "60" and float(row["max_eval_G"]) == expected + 0.5
    # max-critic at 4 rovers: 5.4, 6.4, 7.4, 8.4; sd = sqrt(5/3), half-width t(3) sd / 2
    half = t975(3) * math.sqrt(5 / 3) / 2
    assert (
        f"| max-critic | 4 | {6.9:.2f} +- {half:.2f} | 4 |"
        in (tmp_path / "out" / "cells.md").read_text()
    )
    cells = {r["cell"]: r for r in _rows(tmp_path / "out" / "cells.csv")}
    assert float(cells["max-critic 4"]["ci95_half_width"]) == pytest.approx(half)
    assert float(cells["D 3"]["mean"]) == pytest.approx(1.8) and cells["D 3"]["n"] == "4"
    final = {
        (r["group"], r["n_rovers"]): r
        for r in _rows(tmp_path / "out" / "grid_final_vs_n_rovers.csv")
    }
    assert float(final["D", "3"]["mean"]) == pytest.approx(1.8) and final["D", "3"]["n"] == "4"
    assert float(final["max-critic", "4"]["ci95_half_width"]) == pytest.approx(half)
    assert (tmp_path / "out" / "grid_curves.png").stat().st_size > 0
    assert (tmp_path / "out" / "grid_final_vs_n_rovers.png").stat().st_size > 0


def test_chunks_of_seeds_on_two_machines_equal_the_whole_sweep(tmp_path, sweep, capsys):
    _fake_runs(sweep, tmp_path / "whole", None)
    _results(tmp_path / "whole", tmp_path / "whole-out")
    _fake_runs(sweep, tmp_path / "first", range(0, 2))  # machine 1: seeds 0-1
    _results(tmp_path / "first", tmp_path / "out")
    _fake_runs(sweep, tmp_path / "second", range(2, 4))  # machine 2: seeds 2-3 + the files
    capsys.readouterr()
    _results(tmp_path / "second", tmp_path / "out")
    assert "8 finished runs of earlier machines pooled" in capsys.readouterr().err
    for name in ("runs.csv", "cells.md", "cells.csv", "grid_final_vs_n_rovers.csv"):
        assert (tmp_path / "out" / name).read_text() == (tmp_path / "whole-out" / name).read_text()
    # the learning curves need the runs themselves: machine 2's are its own two seeds
    curves = _rows(tmp_path / "out" / "grid_curves.csv")
    assert {r["n"] for r in curves} == {"2"}


def test_unfinished_runs_are_left_out_and_said_so(tmp_path, sweep, capsys):
    _fake_runs(sweep, tmp_path / "root", range(0, 2))
    going = sorted((tmp_path / "root" / "grid").glob("*_seed=1"))
    for run in going:
        (run / "state.json").write_text('{"generation": 20}')
    _results(tmp_path / "root", tmp_path / "out")
    assert "4 of 8 runs are not finished and are left out" in capsys.readouterr().err
    assert {r["seed"] for r in _rows(tmp_path / "out" / "runs.csv")} == {"0"}


def test_no_final_score_figure_for_a_field_only_one_variant_sets(tmp_path, capsys):
    # trajectory-critics-long: a critic's own fields differ between the two variants only;
    # each group had one point, and three empty figures were drawn.
    path = tmp_path / "sweep.toml"
    path.write_text(SWEEP.replace('"fig8-9-paper"', '"variants"').replace(
        'method = ["D", "max-critic"]\n', "") + """
[[variants]]
method = "D"
[[variants]]
method = "max-critic"
critic_hidden = 20
""")  # fmt: skip
    _fake_runs(Sweep.load(path), tmp_path / "root", None)
    assert (
        main(["results", str(tmp_path / "root" / "variants"), "--out", str(tmp_path / "out")]) == 0
    )
    made = sorted(p.name for p in (tmp_path / "out").glob("*_final_vs_*.png"))
    assert made == ["variants_final_vs_n_rovers.png"]  # not ..._final_vs_critic_hidden


def test_errors_are_one_line(tmp_path, capsys):
    assert main(["results", str(tmp_path / "missing")]) == 2
    (tmp_path / "empty").mkdir()
    assert main(["results", str(tmp_path / "empty")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [
        f"physrover: error: {tmp_path / 'missing'} is not a directory",
        f"physrover: error: {tmp_path / 'empty'}: no finished run (nor earlier rows of sweep "
        "empty)",
    ]


COMPARED = (
    SWEEP.replace('"fig8-9-paper"', '"grid"')
    + """
[[comparisons]]
a = { method = "max-critic" }
b = { method = "D" }

[[comparisons]]
a = { n_rovers = 4 }
b = { n_rovers = 3 }
"""
)


def test_planned_comparisons_of_the_sweep_file_with_holm_over_all(tmp_path, capsys):
    from physrover.analysis.tables import compare_samples
    from physrover.core.stats import holm

    path = tmp_path / "grid.toml"
    path.write_text(COMPARED)
    sweep = Sweep.load(path)
    _fake_runs(sweep, tmp_path / "root", None)  # final G = seed + n_rovers / 10 (+ 5: critic)
    sweep.write_copy(tmp_path / "root", COMPARED)  # what physrover sweep keeps
    _results(tmp_path / "root", tmp_path / "out")
    rows = _rows(tmp_path / "out" / "grid_significance.csv")
    assert [(r["cell"], r["A"], r["B"]) for r in rows] == [
        ("n_rovers=3", "method=max-critic", "method=D"),
        ("n_rovers=4", "method=max-critic", "method=D"),
        ("method=D", "n_rovers=4", "n_rovers=3"),
        ("method=max-critic", "n_rovers=4", "n_rovers=3"),
    ]
    seeds = [0, 1, 2, 3]
    expected = [compare_samples([s + 0.3 + 5 for s in seeds], [s + 0.3 for s in seeds]),
                compare_samples([s + 0.4 + 5 for s in seeds], [s + 0.4 for s in seeds]),
                compare_samples([s + 0.4 for s in seeds], [s + 0.3 for s in seeds]),
                compare_samples([s + 5.4 for s in seeds], [s + 5.3 for s in seeds])]  # fmt: skip
    adjusted = holm([e["p_permutation"] for e in expected])
    for row, want, p in zip(rows, expected, adjusted, strict=True):
        assert float(row["mean_A"]) == pytest.approx(want["mean_A"])
        assert float(row["p_permutation"]) == pytest.approx(want["p_permutation"])
        assert float(row["p_holm"]) == pytest.approx(p) and row["family_size"] == "4"
    text = (tmp_path / "out" / "grid_significance.md").read_text()
    assert "| n_rovers=3 | method=max-critic | method=D | 4/4 |" in text
    assert "grid: 4 planned comparisons (Holm over all)" in capsys.readouterr().err


@pytest.mark.parametrize(
    ("table", "message"),
    [
        ('[[comparisons]]\na = { method = "D" }\n', "comparisons[0]: needs a and b"),
        (
            '[[comparisons]]\na = { method = "D" }\nb = { method = "G" }\nwhen = 1\n',
            "comparisons[0]: needs a and b (and may have where)",
        ),
        (
            '[[comparisons]]\na = { method = "D" }\nb = { method = "G" }\nwhere = { n_req = 2 }\n',
            "comparisons[0].where: must be a table of grid fields and lists",
        ),
        (
            '[[comparisons]]\na = { method = "D" }\nb = { method = "G" }\nwhere = { nreq = [2] }\n',
            "nreq: unknown",
        ),
        ('[[comparisons]]\na = { method = "D" }\nb = { method = "D" }\n', "pick the same runs"),
        ('[[comparisons]]\na = { methd = "D" }\nb = { method = "G" }\n', "methd: unknown"),
        ('[[comparisons]]\na = {}\nb = { method = "G" }\n', "comparisons[0].a: must be a"),
    ],
)
def test_a_bad_comparison_is_a_one_line_error(tmp_path, table, message):
    from physrover.config import ConfigError

    path = tmp_path / "bad.toml"
    path.write_text(SWEEP + table)
    with pytest.raises(ConfigError) as error:
        Sweep.load(path)
    assert message in str(error.value) and "\n" not in str(error.value)


def test_a_sweep_keeps_a_copy_of_its_file_for_results(tmp_path):
    text = """
[sweep]
name = "kept"
[base.domain]
n_rovers = 3
n_req = 1
steps = 5
[base.learn]
generations = 1
population = 4
eval_episodes = 1
[grid]
method = ["D", "G"]
[[comparisons]]
a = { method = "D" }
b = { method = "G" }
"""
    path = tmp_path / "kept.toml"
    path.write_text(text)
    assert main(["sweep", str(path), "--root", str(tmp_path / "root"), "--workers", "1"]) == 0
    assert (tmp_path / "root" / "kept" / "sweep.toml").read_text() == text
    assert Sweep.load(tmp_path / "root" / "kept" / "sweep.toml").comparisons == (
        {"a": {"method": "D"}, "b": {"method": "G"}},
    )


def test_a_field_one_side_leaves_out_is_the_bases_value(tmp_path):
    # b names no hidden size: it is the base's 32, not every size the variants ran
    text = (
        SWEEP.replace('"fig8-9-paper"', '"sizes"').replace("n_rovers = [3, 4]", "")
        + """
[[variants]]
[[variants]]
hidden = 16
[[variants]]
hidden = 64
[[comparisons]]
a = { method = "D", hidden = 16 }
b = { method = "D" }
"""
    )
    path = tmp_path / "sizes.toml"
    path.write_text(text)
    sweep = Sweep.load(path)
    _fake_runs(sweep, tmp_path / "root", None)
    sweep.write_copy(tmp_path / "root", text)
    assert main(["results", str(tmp_path / "root" / "sizes"), "--out", str(tmp_path / "o")]) == 0
    (row,) = _rows(tmp_path / "o" / "sizes_significance.csv")
    assert (row["A"], row["B"], row["n_A"], row["n_B"]) == ("method=D hidden=16", "method=D",
                                                             "4", "4")  # fmt: skip
