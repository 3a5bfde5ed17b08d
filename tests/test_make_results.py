"""experiments/make_results.py carries a final-score sweep across machines: a sweep run in
chunks of seeds on machines that do not keep each other's run directories gives the same
runs.csv rows, cells.md table and figure numbers as the whole sweep found on one disk."""

import csv
import json
import math
import sys
from pathlib import Path

import pytest
from conftest import load_file

from physrover.analysis.claim_tests import (
    claim_comparisons,
    claim_trends,
    load_claims,
    write_claims,
)
from physrover.analysis.results import read_rows
from physrover.config import RunConfig
from physrover.experiment.sweep import Sweep

ROOT = Path(__file__).parents[1]

SWEEP = """
[sweep]
name = "fig8-9-paper"
seeds = 4
[base.domain]
n_req = 1
[base.learn]
generations = 60
[grid]
method = ["D", "max-critic"]
n_rovers = [3, 4]
"""


@pytest.fixture
def make_results(monkeypatch):
    module = load_file(ROOT / "experiments" / "make_results.py", "make_results", monkeypatch)

    def run(root: Path, out: Path, last: int = 50) -> None:
        monkeypatch.setattr(module, "OUT", out)
        monkeypatch.setattr(
            sys, "argv", ["make_results.py", "--root", str(root), "--last", str(last)]
        )
        module.main()

    return run


def _final(spec) -> float:
    """A made-up final score of a run, different for every run: seed + n_rovers / 10 (+ 5
    for the max critic)."""
    config = RunConfig.from_toml(spec.config_toml)
    bonus = 5.0 * (config.learn.method == "max-critic")
    return config.learn.seed + config.domain.n_rovers / 10 + bonus


def _fake_runs(sweep: Sweep, root: Path, seeds) -> None:
    """Run directories of the sweep's runs of ``seeds`` as training writes them (config and
    metrics of 60 generations; the last 50 generations' eval G average to :func:`_final`)."""
    _fake_runs_of(sweep.runs(root, seeds=seeds))


def _fake_runs_of(specs) -> None:
    """:func:`_fake_runs` of the run specs given."""
    for spec in specs:
        out = Path(spec.out)
        out.mkdir(parents=True)
        (out / "config.toml").write_text(spec.config_toml)
        final = _final(spec)
        with open(out / "metrics.csv", "w", newline="") as f:
            writer = csv.writer(f)
            writer.writerow(["generation", "eval_G", "train_G_mean", "fitness_mean",
                             "critic_loss", "wall_seconds"])  # fmt: skip
            curve = [0.0] * 10 + [final - 0.5, final + 0.5] * 25
            for g, value in enumerate(curve, start=1):
                writer.writerow([g, value, 0.0, 0.0, "nan", 1.0])
        (out / "state.json").write_text('{"generation": 60}')  # finished


def _outputs(out: Path) -> tuple:
    rows = [r for r in csv.DictReader(open(out / "runs.csv")) if r["sweep"] == "fig8-9-paper"]
    figure = (out / "fig8-9_paper_final_vs_rovers_nreq1.csv").read_text()
    return rows, (out / "cells.md").read_text(), figure


def _numbers(figure_csv: str) -> list[float]:
    return [float(v) for line in figure_csv.splitlines()[1:] for v in line.split(",")[1:]]


def test_chunks_of_seeds_on_fresh_machines_equal_the_whole_sweep(tmp_path, make_results):
    path = tmp_path / "sweep.toml"
    path.write_text(SWEEP)
    sweep = Sweep.load(path)
    whole, first, second = (tmp_path / name for name in ("whole", "first", "second"))
    _fake_runs(sweep, whole / "root", None)
    make_results(whole / "root", whole / "results")
    _fake_runs(sweep, first / "root", range(0, 2))  # the first machine: seeds 0-1
    make_results(first / "root", first / "results")
    (second / "results").mkdir(parents=True)  # the second: seeds 2-3 and the committed files
    for name in ("runs.csv", "cells.md"):
        (second / "results" / name).write_text((first / "results" / name).read_text())
    _fake_runs(sweep, second / "root", range(2, 5))
    for going in (second / "root" / "fig8-9-paper").glob("*_seed=4"):  # still running
        (going / "state.json").write_text('{"generation": 2}')  # left out
    make_results(second / "root", second / "results")
    rows, cells, figure = _outputs(whole / "results")
    pooled = _outputs(second / "results")
    assert pooled[:2] == (rows, cells)
    # runs.csv keeps final scores to 4 decimals: the pooled figure's numbers agree to that
    assert _numbers(pooled[2]) == pytest.approx(_numbers(figure), abs=1e-4)
    assert len(rows) == 16
    # max-critic at 4 rovers: seeds 0-3 score 5.4, 6.4, 7.4, 8.4: mean 6.9 over n = 4
    cell = {(r["group"], float(r["n_rovers"])): r for r in csv.DictReader(figure.splitlines())}
    assert len(cell) == 4 and {int(r["n"]) for r in cell.values()} == {4}
    assert float(cell["max-critic", 4.0]["mean"]) == pytest.approx(6.9)
    assert float(cell["D", 3.0]["mean"]) == pytest.approx(1.8)
    assert "| max-critic | 1 | 4 | 6.90 +- " in cells
    # the first machine alone: two seeds a cell
    assert "| max-critic | 1 | 4 | 5.90 +- " in _outputs(first / "results")[1]


def test_a_chunk_with_one_finished_run_keeps_the_earlier_rows_grid(tmp_path):
    """A later machine whose chunk has finished one run (its grid fields vary in no run
    found there) pools the earlier rows with their grid columns and adds its run's values,
    so the cells stay those of the whole grid."""
    from physrover.analysis.results import write_results

    path = tmp_path / "sweep.toml"
    path.write_text(SWEEP)
    sweep = Sweep.load(path)
    _fake_runs(sweep, tmp_path / "first", range(0, 2))
    write_results([tmp_path / "first" / "fig8-9-paper"], tmp_path / "results")
    one = next(spec for spec in sweep.runs(tmp_path / "second", seeds=range(2, 3))
               if "max-critic" in spec.out and "n_rovers=4" in spec.out)  # fmt: skip
    _fake_runs_of([one])
    write_results([tmp_path / "second" / "fig8-9-paper"], tmp_path / "results")
    rows = read_rows(tmp_path / "results" / "runs.csv")
    assert len(rows) == 9 and all(row["n_rovers"] in ("3", "4") for row in rows)
    assert {(r["method"], r["n_rovers"], r["seed"]) for r in rows} >= {("max-critic", "4", "2")}
    cells = (tmp_path / "results" / "cells.md").read_text()
    assert "| max-critic | 4 | 6.40 +- " in cells  # seeds 0-2: 5.4, 6.4, 7.4
    assert "| D | 3 | 0.80 +- " in cells  # seeds 0-1: 0.3, 1.3


def test_unfinished_kept_rows_are_dropped(tmp_path, make_results):
    """A row of a run that was still going when its machine's results were made is not a
    final score: only rows with the sweep's full length are kept (rows written before
    make_results left unfinished runs out)."""
    path = tmp_path / "sweep.toml"
    path.write_text(SWEEP)
    sweep = Sweep.load(path)
    first, second = tmp_path / "first", tmp_path / "second"
    _fake_runs(sweep, first / "root", range(0, 1))
    cut = first / "root" / "fig8-9-paper" / "method=D_n_rovers=3_seed=0" / "metrics.csv"
    cut.write_text("".join(cut.read_text().splitlines(keepends=True)[:3]))  # 2 generations
    make_results(first / "root", first / "results")
    (second / "results").mkdir(parents=True)
    for name in ("runs.csv", "cells.md"):
        (second / "results" / name).write_text((first / "results" / name).read_text())
    _fake_runs(sweep, second / "root", range(1, 2))
    make_results(second / "root", second / "results")
    runs = {row["run"] for row in _outputs(second / "results")[0]}
    assert "method=D_n_rovers=3_seed=0" not in runs
    assert "method=max-critic_n_rovers=3_seed=0" in runs and len(runs) == 7


def test_another_last_pools_nothing(tmp_path, make_results, capsys):
    """Committed final scores average the last 50 generations: with --last 20 they are
    neither pooled with finals of another definition nor dropped: the sweep is left as
    committed, and the script says so."""
    path = tmp_path / "sweep.toml"
    path.write_text(SWEEP)
    sweep = Sweep.load(path)
    first, second = tmp_path / "first", tmp_path / "second"
    _fake_runs(sweep, first / "root", range(0, 1))
    make_results(first / "root", first / "results")
    (second / "results").mkdir(parents=True)
    for name in ("runs.csv", "cells.md"):
        (second / "results" / name).write_text((first / "results" / name).read_text())
    _fake_runs(sweep, second / "root", range(1, 2))
    files = [second / "results" / name for name in ("runs.csv", "cells.md")]
    committed = [f.read_text() for f in files]
    make_results(second / "root", second / "results", last=20)
    assert "not the committed rows' 50" in capsys.readouterr().out
    assert [f.read_text() for f in files] == committed
    assert not list((second / "results").glob("*.png"))


def test_runs_csv_names_the_code_and_cpu_that_trained_each_run(tmp_path, make_results):
    """A run trained in two pieces by other code on other CPUs lists both; a run resumed
    from provenance-less generations starts with '?'; a run without provenance.json has
    empty columns, and another machine's make_results keeps the pooled rows' values."""
    path = tmp_path / "sweep.toml"
    path.write_text(SWEEP)
    sweep = Sweep.load(path)
    _fake_runs(sweep, tmp_path / "root", range(0, 1))
    runs = tmp_path / "root" / "fig8-9-paper"

    def segment(start, code, cpu):
        return {"from_generation": start, "code": code * 64, "llvm_cpu": cpu}

    pieces = [segment(0, "a", "znver4"), segment(30, "b", "emeraldrapids"), segment(45, "b", "x")]
    (runs / "method=D_n_rovers=3_seed=0" / "provenance.json").write_text(
        json.dumps({"segments": pieces})
    )
    (runs / "method=D_n_rovers=4_seed=0" / "provenance.json").write_text(
        json.dumps({"segments": [segment(20, "c", "znver4")]})
    )
    make_results(tmp_path / "root", tmp_path / "results")
    rows = {r["run"]: r for r in csv.DictReader(open(tmp_path / "results" / "runs.csv"))}
    two = rows["method=D_n_rovers=3_seed=0"]
    assert (two["code"], two["cpu"]) == ("a" * 12 + "+" + "b" * 12, "znver4+emeraldrapids+x")
    assert rows["method=D_n_rovers=4_seed=0"]["code"] == "?+" + "c" * 12
    assert rows["method=max-critic_n_rovers=3_seed=0"]["code"] == ""
    later = tmp_path / "later"  # the next machine: seed 1 on disk, seed 0 only in runs.csv
    (later / "results").mkdir(parents=True)
    for name in ("runs.csv", "cells.md"):
        (later / "results" / name).write_text((tmp_path / "results" / name).read_text())
    _fake_runs(sweep, later / "root", range(1, 2))
    make_results(later / "root", later / "results")
    kept = {r["run"]: r for r in csv.DictReader(open(later / "results" / "runs.csv"))}
    assert kept["method=D_n_rovers=4_seed=0"]["code"] == "?+" + "c" * 12
    assert kept["method=D_n_rovers=3_seed=1"]["code"] == "" and len(kept) == 8


def test_rows_written_before_the_provenance_columns_pool(tmp_path, make_results):
    """A committed runs.csv without the code and cpu columns (before 0.4.0's last
    commits) pools with runs found on disk: its rows get empty values."""
    path = tmp_path / "sweep.toml"
    path.write_text(SWEEP)
    sweep = Sweep.load(path)
    _fake_runs(sweep, tmp_path / "first" / "root", range(0, 1))
    make_results(tmp_path / "first" / "root", tmp_path / "first" / "results")
    rows = list(csv.DictReader(open(tmp_path / "first" / "results" / "runs.csv")))
    old = tmp_path / "later" / "results"
    old.mkdir(parents=True)
    with open(old / "runs.csv", "w", newline="") as f:
        fields = [k for k in rows[0] if k not in ("code", "cpu")]
        writer = csv.DictWriter(f, fieldnames=fields, extrasaction="ignore")
        writer.writeheader()
        writer.writerows(rows)
    _fake_runs(sweep, tmp_path / "later" / "root", range(1, 2))
    make_results(tmp_path / "later" / "root", old)
    pooled = list(csv.DictReader(open(old / "runs.csv")))
    assert len(pooled) == 8 and {r["code"] for r in pooled} == {""}
    assert {r["seed"] for r in pooled} == {"0", "1"}


PHYSICS = """
[sweep]
name = "{name}"
seeds = 2
[base.domain]
n_rovers = 15
n_req = 3
motion = "physics"
[base.learn]
generations = 60
[grid]
method = ["{method}"]
[[variants]]
collisions = false
[[variants]]
collisions = true
"""


def test_the_mean_critic_under_physics_is_set_against_physics_long_on_another_machine(
    tmp_path, make_results
):
    """physics-long-mean, run where physics-long's run directories are not, adds its rows
    to runs.csv beside physics-long's kept rows, one seed per machine (it is pooled like
    fig8-9-paper), and the paper-claims file compares the max critic of one with the mean
    critic of the other, per motion model (claim 12)."""
    machines = [tmp_path / name for name in ("first", "second", "third")]
    for root, name, method, seeds in (
        (machines[0], "physics-long", "max-critic", None),
        (machines[1], "physics-long-mean", "mean-critic", range(0, 1)),
        (machines[2], "physics-long-mean", "mean-critic", range(1, 2)),
    ):
        path = tmp_path / f"{name}.toml"
        path.write_text(PHYSICS.format(name=name, method=method))
        _fake_runs(Sweep.load(path), root / "root", seeds)
    make_results(machines[0] / "root", machines[0] / "results")
    for before, now in zip(machines[:-1], machines[1:], strict=True):  # the committed files
        (now / "results").mkdir(parents=True)
        for name in ("runs.csv", "cells.md"):
            (now / "results" / name).write_text((before / "results" / name).read_text())
        make_results(now / "root", now / "results")
    last = machines[2] / "results"
    rows = list(csv.DictReader(open(last / "runs.csv")))
    models = ("physics", "physics", "physics+collisions", "physics+collisions")  # 2 seeds
    assert [(r["sweep"], r["method"], r["motion"]) for r in rows] == [
        *[("physics-long", "max-critic", m) for m in models],
        *[("physics-long-mean", "mean-critic", m) for m in models],
    ]
    assert [r["seed"] for r in rows[4:]] == ["0", "1", "0", "1"]
    cells = (last / "cells.md").read_text()  # seeds 0 and 1: finals 1.5 and 2.5
    assert "### physics-long-mean" in cells and "| mean-critic | 3 | physics | 2.00 +- " in cells
    figure = list(csv.DictReader(open(last / "physics-long-mean_final_vs_nreq.csv")))
    assert [(r["group"], float(r["mean"]), int(r["n"])) for r in figure] == [
        ("mean-critic physics", 2.0, 2), ("mean-critic physics+collisions", 2.0, 2)
    ]  # fmt: skip
    found = claim_comparisons(read_rows(last / "runs.csv"), load_claims("paper-claims")[1])
    claim = [r for r in found if r["claim"] == 12]
    assert [(r["sweep"], r["A"], r["B"]) for r in claim] == [
        ("physics-long vs physics-long-mean", f"max-critic ({m}) n_req=3 rovers=15",
         f"mean-critic ({m}) n_req=3 rovers=15")
        for m in ("physics", "physics+collisions")
    ]  # fmt: skip
    # finals: seed + 15 / 10 (+ 5 for the max critic), seeds 0 and 1
    assert [(r["mean_A"], r["mean_B"], r["family_size"]) for r in claim] == [(7.0, 2.0, 2)] * 2


def test_trends_over_team_size(tmp_path):
    """paper-claims' trend table: Spearman's rho of the final scores with the team size per
    (sweep, method, n_req), Holm over the sweep; cells short of seeds are left out."""
    rows = []
    for size in (6, 9, 12, 15):
        for method, finals in (("max-critic", [size / 3, size / 3 + 0.1]),  # rises
                               ("average", [0.0, 0.0]),  # flat: no trend
                               ("mean-critic", [1.0] if size == 15 else [1.0, 2.0])):  # fmt: skip
            rows += [{"sweep": "fig8-9-paper", "method": method, "n_req": "4",
                      "n_rovers": str(size), "feedback": "D", "motion": "ideal",
                      "variant": "", "final_G": str(g)} for g in finals]  # fmt: skip
    rows.append({**rows[0], "motion": "physics", "final_G": "99"})  # not the idealised cell
    doc = load_claims("paper-claims")[1]
    trends = claim_trends(rows, doc)
    assert [(r["method"], r["n"]) for r in trends] == [
        ("average", "2/2/2/2"),
        ("max-critic", "2/2/2/2"),
    ]
    flat, rising = trends
    # centred ranks of the sizes (-3, -3, -1, -1, 1, 1, 3, 3), of the scores -3.5 .. 3.5:
    # rho = 40 / sqrt(40 * 42), the largest |rho| the tied sizes allow
    assert flat["p_permutation"] == 1.0 and rising["rho"] == pytest.approx(40 / math.sqrt(1680))
    # 8 scores, 8! = 40,320 orderings (exact): as extreme are the 2^4 orders within the
    # pairs of each size, either way round: p = 2 * 16 / 40320; Holm over the two trends
    assert rising["p_permutation"] == pytest.approx(32 / 40320)
    assert (rising["p_holm"], rising["family_size"]) == (pytest.approx(64 / 40320), 2)
    assert rising["mean_6"] == pytest.approx(2.05)
    write_claims(rows, {**doc, "comparisons": []}, "claims", tmp_path)
    assert (
        "| fig8-9-paper | max-critic | 4 | 2/2/2/2 | 2.05 | 3.05 | 4.05 | 5.05 | 0.976 |"
        in (tmp_path / "claims_trend.md").read_text()
    )
