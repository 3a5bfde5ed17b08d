"""Learning-curve and final-score numbers (plots.py)."""

import csv

import numpy as np
import pytest

from physrover import plots
from physrover.config import RunConfig
from physrover.plots import curve_table, final_table, load_runs, mean_ci, t975, write_csv
from physrover.runs import prepare_run_dir


def test_t_quantiles():
    assert t975(1) == 12.706 and t975(9) == 2.262
    assert t975(60) == pytest.approx(2.0003, abs=2e-4)
    assert t975(1000) == pytest.approx(1.9623, abs=2e-4)


def _fake_run(root, name, method, n_req, curve):
    config = RunConfig().with_overrides({"method": method, "n_req": n_req})
    prepare_run_dir(root / name, config)
    with open(root / name / "metrics.csv", "a", newline="") as f:
        for g, value in enumerate(curve):
            f.write(f"{g},{value},0,0,nan,0\n")
    return root / name


def test_curve_numbers(tmp_path):
    runs = [
        _fake_run(tmp_path, "a", "D", 3, [0.0, 1.0, 2.0]),
        _fake_run(tmp_path, "b", "D", 3, [2.0, 3.0, 4.0, 9.0]),  # longer: cut to 3
        _fake_run(tmp_path, "c", "D", 3, [1.0, 2.0, 6.0]),
        _fake_run(tmp_path, "d", "max-critic", 3, [5.0, 5.0, 5.0]),
    ]
    table = curve_table(load_runs(runs))
    d = table["D"]
    np.testing.assert_allclose(d["mean"], [1.0, 2.0, 4.0])
    # sd over seeds at generation 0: sd(0, 2, 1) = 1; half-width = t(2) * 1 / sqrt(3).
    np.testing.assert_allclose(d["ci"][0], 4.303 / np.sqrt(3))
    np.testing.assert_allclose(d["ci"][2], 4.303 * 2.0 / np.sqrt(3))
    assert d["n"] == 3 and np.isnan(table["max-critic"]["ci"]).all()
    write_csv(table, tmp_path / "c.csv", "generation")
    rows = list(csv.DictReader(open(tmp_path / "c.csv")))
    half = repr(float(4.303 * 2 / np.sqrt(3)))
    expected = {"group": "D", "generation": "2", "mean": "4.0", "ci95_half_width": half, "n": "3"}
    assert rows[2] == expected


def test_final_numbers_by_field(tmp_path):
    runs = [
        _fake_run(tmp_path, "a", "D", 3, [0.0, 4.0]),
        _fake_run(tmp_path, "b", "D", 3, [0.0, 6.0]),
        _fake_run(tmp_path, "c", "D", 5, [0.0, 1.0]),
    ]
    table = final_table(load_runs(runs), "n_req", last=1)
    np.testing.assert_allclose(table["D"]["x"], [3, 5])
    np.testing.assert_allclose(table["D"]["mean"], [5.0, 1.0])
    mean, ci, n = mean_ci(np.array([4.0, 6.0]))
    assert table["D"]["ci"][0] == ci == pytest.approx(12.706 * np.sqrt(2) / np.sqrt(2))


def test_a_method_keeps_its_colour_across_figures():
    from physrover.config import METHODS

    assert set(plots.METHOD_COLOURS) == set(METHODS)
    assert len(set(plots.METHOD_COLOURS.values())) == len(METHODS)
    four = plots.group_colours(["D", "average", "max-critic", "mean-critic"])
    three = plots.group_colours(["average", "max-critic", "mean-critic"])
    assert all(three[m] == four[m] for m in three)
    # labels that are not bare method names fall back to the axes' colour cycle
    assert plots.group_colours(["D ideal", "D physics"]) == {"D ideal": None, "D physics": None}
