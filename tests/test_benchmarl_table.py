"""experiments/benchmarl_table.py, BenchMARL's row of the standing table, without BenchMARL:
``physrover benchmarl`` is replaced by a stand-in that writes the csv logger's evaluation
file, so the cell's overrides, its final G (the mean of the last evaluations), resuming
after an interrupted cell and the report's hand-worked intervals are checked here."""

import csv
import json
import sys
from importlib import metadata
from pathlib import Path

import pytest
from conftest import load_file

ROOT = Path(__file__).parents[1]
METRIC = "eval_reward_episode_reward_mean"


@pytest.fixture
def table(monkeypatch):
    module = load_file(ROOT / "experiments" / "benchmarl_table.py", "benchmarl_table", monkeypatch)
    version = metadata.version  # BenchMARL itself is not installed with the test extras
    monkeypatch.setattr(metadata, "version", lambda d: "9.9" if d == "benchmarl" else version(d))
    return module


def fake_benchmarl(returns: list[float], calls: list[list[str]]):
    """A stand-in for ``subprocess.run([physrover, "benchmarl", "--out", DIR, *overrides])``:
    it records the command and writes ``returns`` as BenchMARL's csv logger does
    (``DIR/<experiment>/scalars/<metric>.csv``, rows of ``step,value``)."""

    def run(command, check):
        assert check is True
        calls.append(command)
        out = Path(command[command.index("--out") + 1])
        scalars = out / "mappo_rover_domain_mlp__0" / "scalars"
        scalars.mkdir(parents=True)
        with (scalars / f"{METRIC}.csv").open("w", newline="") as f:
            csv.writer(f).writerows([i * 60000, r] for i, r in enumerate(returns))

    return run


def test_a_cell_runs_physrover_quick_at_the_stated_budget(table, monkeypatch, tmp_path):
    calls = []
    returns = [0.0, 4.0, 10.0, 9.0, 8.0, 7.0, 6.0, 5.0]
    monkeypatch.setattr(table.subprocess, "run", fake_benchmarl(returns, calls))
    result = table.train_cell(tmp_path, 3, 7)
    ((exe, command, flag, out, *overrides),) = calls
    assert (Path(exe).name, command, flag) == ("physrover", "benchmarl", "--out")
    assert Path(out) == tmp_path / "n_req=3_seed=7" / "benchmarl"
    assert overrides == ["experiment=physrover_quick", "task.n_req=3", "seed=7",
                         "experiment.max_n_iters=210", "experiment.evaluation_interval=60000",
                         "experiment.evaluation_episodes=100"]  # fmt: skip
    conf = ROOT / "physrover" / "envs" / "benchmarl_conf"
    quick = (conf / "experiment" / "physrover_quick.yaml").read_text()
    assert "\non_policy_collected_frames_per_batch: 6000\n" in quick
    assert "\nsteps: 50\n" in (conf / "task" / "physrover" / "rover_domain.yaml").read_text()
    assert result["episodes"] == 25_200  # 210 iterations of 6000 / 50 episodes
    assert result["final_G"] == pytest.approx((8 + 7 + 6 + 5 + 9) / 5)  # the last 5
    assert result["max_eval_G"] == 10.0 and result["evaluations"] == 8
    assert result["returns"] == returns and result["benchmarl"] == "9.9"
    saved = json.loads((tmp_path / "n_req=3_seed=7" / "result.json").read_text())
    assert saved == result


def test_a_cell_with_too_few_evaluations_fails_without_a_result(table, monkeypatch, tmp_path):
    monkeypatch.setattr(table.subprocess, "run", fake_benchmarl([0.0, 1.0, 2.0, 3.0], []))
    with pytest.raises(RuntimeError, match="4 evaluations, expected >= 5"):
        table.train_cell(tmp_path, 1, 0)
    assert not (tmp_path / "n_req=1_seed=0" / "result.json").exists()


def test_run_trains_only_the_cells_without_a_result_and_restarts_an_interrupted_one(
    table, monkeypatch, tmp_path, capsys
):
    done = tmp_path / "n_req=1_seed=0"
    done.mkdir()
    (done / "result.json").write_text("{}")
    interrupted = tmp_path / "n_req=2_seed=0" / "benchmarl" / "old"
    interrupted.mkdir(parents=True)  # a cell stopped mid-run: no result.json
    calls = []
    monkeypatch.setattr(table.subprocess, "run", fake_benchmarl([1.0] * 6, calls))
    monkeypatch.setattr(sys, "argv", ["benchmarl_table.py", "run", "--root", str(tmp_path),
                                      "--seeds", "0:2", "--n-req", "1,2"])  # fmt: skip
    table.main()
    trained = [Path(c[c.index("--out") + 1]).parent.name for c in calls]
    assert trained == ["n_req=2_seed=0", "n_req=1_seed=1", "n_req=2_seed=1"]
    assert not interrupted.exists()  # trained again from the start
    assert "4 cells, 1 done, 3 to train" in capsys.readouterr().out


def test_report_gives_hand_worked_intervals_and_the_seeds_that_learn(table, monkeypatch, tmp_path):
    root, out = tmp_path / "runs", tmp_path / "out"
    finals = {(1, 0): 9.656, (2, 0): 1.0, (2, 1): 2.0, (2, 2): 3.0,
              (5, 0): 0.0, (5, 1): 0.4, (5, 2): 0.6}  # fmt: skip
    for (n_req, seed), g in finals.items():
        cell = root / table.cell_name(n_req, seed)
        cell.mkdir(parents=True)
        row = dict.fromkeys(table.FIELDS, "x") | {
            "n_req": n_req,
            "seed": seed,
            "final_G": g,
            "max_eval_G": g + 0.5,
        }
        (cell / "result.json").write_text(json.dumps(row))
    monkeypatch.setattr(sys, "argv", ["benchmarl_table.py", "report", "--root", str(root),
                                      "--out", str(out)])  # fmt: skip
    table.main()
    lines = (out / "cells.md").read_text().splitlines()
    # n_req 2: mean 2, sd 1, t(0.975, 2 dof) = 4.3027 -> 4.3027 / sqrt(3) = 2.484.
    # n_req 5: mean 1/3, sd 0.3055 -> 4.3027 x 0.3055 / sqrt(3) = 0.759; one seed > 0.5.
    assert lines[2:] == ["| 1 | 9.66 | 1 | 1 | 10.16 |",
                         "| 2 | 2.00 +- 2.48 | 3 | 3 | 3.50 |",
                         "| 5 | 0.33 +- 0.76 | 3 | 1 | 1.10 |"]  # fmt: skip
    rows = list(csv.DictReader((out / "runs.csv").open()))
    assert [(r["n_req"], r["seed"]) for r in rows] == [(str(n), str(s)) for n, s in sorted(finals)]
    assert list(rows[0]) == list(table.FIELDS)
