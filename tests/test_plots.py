"""Learning-curve and final-score numbers and figures (plots.py)."""

import csv
import math
from pathlib import Path

import numpy as np
import pytest

from physrover.analysis import plots
from physrover.analysis.plots import curve_table, final_table, load_runs, mean_ci, t975, write_csv
from physrover.config import ConfigError, RunConfig
from physrover.experiment.store import prepare_run_dir
from physrover.learn.stats import stats_header


def test_t_quantiles():
    assert t975(1) == 12.706 and t975(9) == 2.262
    assert t975(60) == pytest.approx(2.0003, abs=2e-4)
    assert t975(1000) == pytest.approx(1.9623, abs=2e-4)


def _fake_run(root, name, method, n_req, curve, **overrides):
    """A run directory with ``curve`` as eval G of generations 1, 2, ... (the config: the
    defaults with ``method``, ``n_req`` and any other ``overrides`` by field name)."""
    config = RunConfig().with_overrides({"method": method, "n_req": n_req, **overrides})
    prepare_run_dir(root / name, config)
    with open(root / name / "metrics.csv", "a", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=stats_header())
        for g, value in enumerate(curve, start=1):
            writer.writerow({k: 0 for k in stats_header()} | {"generation": g, "eval_G": value})
    return root / name


def _csv_rows(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


@pytest.fixture
def figures(monkeypatch):
    """The figures the code saves, as they are when saved (plots close them after)."""
    from matplotlib.figure import Figure

    saved = []
    original = Figure.savefig

    def savefig(self, *args, **kwargs):
        saved.append(self)
        return original(self, *args, **kwargs)

    monkeypatch.setattr(Figure, "savefig", savefig)
    return saved


def _legend(fig) -> list[str]:
    return [t.get_text() for t in fig.axes[0].get_legend().get_texts()]


def test_curve_numbers(tmp_path):
    runs = [
        _fake_run(tmp_path, "a", "D", 3, [0.0, 1.0, 2.0]),
        _fake_run(tmp_path, "b", "D", 3, [2.0, 3.0, 4.0, 9.0]),  # longer: cut to 3
        _fake_run(tmp_path, "c", "D", 3, [1.0, 2.0, 6.0]),
        _fake_run(tmp_path, "d", "max-critic", 3, [5.0, 5.0, 5.0]),
    ]
    table = curve_table(load_runs(runs))
    assert list(table) == ["D", "max-critic"]  # only the method differs: bare names
    d = table["D"]
    np.testing.assert_array_equal(d["generation"], [1, 2, 3])  # the metrics' numbering
    np.testing.assert_allclose(d["mean"], [1.0, 2.0, 4.0])
    # sd over seeds at generation 1: sd(0, 2, 1) = 1; half-width = t(2) * 1 / sqrt(3).
    np.testing.assert_allclose(d["ci"][0], 4.303 / np.sqrt(3))
    np.testing.assert_allclose(d["ci"][2], 4.303 * 2.0 / np.sqrt(3))
    assert d["n"] == 3 and np.isnan(table["max-critic"]["ci"]).all()
    assert table.messages == ["D: 3 runs cut to the shortest, 3 generations (longest 4)"]
    write_csv(table, tmp_path / "c.csv", "generation")
    rows = _csv_rows(tmp_path / "c.csv")
    half = repr(float(4.303 * 2 / np.sqrt(3)))
    expected = {
        "group": "D",
        "generation": "3",
        "episodes": "150",  # method D: one round of k = 50 episodes a generation
        "mean": "4.0",
        "ci95_half_width": half,
        "n": "3",
        "raw_mean": "4.0",
        "raw_ci95_half_width": half,
        "smooth_window": "1",
    }
    assert rows[2] == expected


def test_generations_come_from_the_metrics(tmp_path):
    run = _fake_run(tmp_path, "a", "D", 3, [1.0, 2.0, 3.0])
    lines = (run / "metrics.csv").read_text().splitlines()
    # the run's rows are generations 5..7 (as a resumed, trimmed file might hold)
    shifted = [lines[0]] + [
        f"{g + 4}{line[line.index(',') :]}" for g, line in enumerate(lines[1:], 1)
    ]
    (run / "metrics.csv").write_text("\n".join(shifted) + "\n")
    (loaded,) = load_runs([run])
    np.testing.assert_array_equal(loaded.generation, [5, 6, 7])
    np.testing.assert_array_equal(curve_table([loaded])["D"]["generation"], [5, 6, 7])


def test_runs_differing_in_a_config_field_are_never_pooled(tmp_path):
    runs = [
        _fake_run(tmp_path, "a", "max-critic", 3, [1.0, 2.0]),
        _fake_run(tmp_path, "b", "max-critic", 4, [3.0, 4.0]),
    ]
    table = curve_table(load_runs(runs))
    assert list(table) == ["max-critic n_req=3", "max-critic n_req=4"]
    assert table["max-critic n_req=3"]["n"] == 1
    np.testing.assert_allclose(table["max-critic n_req=4"]["mean"], [3.0, 4.0])
    # --by adds its fields to the label even when they are equal
    labels = {r.group for r in load_runs(runs, by=("motion",))}
    assert labels == {"max-critic n_req=3 motion=ideal", "max-critic n_req=4 motion=ideal"}


def test_runs_differing_only_in_seed_are_pooled(tmp_path):
    runs = [
        _fake_run(tmp_path, "a", "D", 3, [1.0, 2.0], seed=0),
        _fake_run(tmp_path, "b", "D", 3, [3.0, 4.0], seed=1, checkpoint_every=7),
    ]
    table = curve_table(load_runs(runs))
    assert list(table) == ["D"] and table["D"]["n"] == 2
    np.testing.assert_allclose(table["D"]["mean"], [2.0, 3.0])
    assert table.messages == []


def test_runs_of_different_lengths_in_generations_are_not_pooled(tmp_path):
    runs = [
        _fake_run(tmp_path, "a", "max-critic", 3, [1.0, 2.0, 3.0], generations=300),
        _fake_run(tmp_path, "b", "max-critic", 3, [1.0, 2.0], generations=2000, seed=1),
        _fake_run(tmp_path, "c", "max-critic", 4, [5.0, 6.0], generations=2000),
    ]
    table = curve_table(load_runs(runs))
    assert sorted(table) == [
        "max-critic n_req=3 generations=2000",
        "max-critic n_req=3 generations=300",
        "max-critic n_req=4 generations=2000",
    ]
    assert all(cols["n"] == 1 for cols in table.values())
    np.testing.assert_array_equal(
        table["max-critic n_req=3 generations=300"]["generation"], [1, 2, 3]
    )
    assert table.messages == []  # nothing was cut


def test_band_is_clipped_to_the_range_of_G_but_the_csv_is_raw(tmp_path, figures):
    g_max = 10.0  # default POI values 1..4
    runs = [
        _fake_run(tmp_path, "a", "D", 3, [0.0, 10.0], seed=0),
        _fake_run(tmp_path, "b", "D", 3, [1.0, 9.0], seed=1),
    ]
    table = curve_table(load_runs(runs))
    cols = table["D"]
    assert cols["g_max"] == g_max
    raw_low, raw_high = cols["mean"] - cols["ci"], cols["mean"] + cols["ci"]
    assert raw_low[0] < 0 and raw_high[1] > g_max  # the case the clipping is for
    low, high = plots.band(cols["mean"], cols["ci"], cols["g_max"])
    np.testing.assert_allclose(low, [0.0, raw_low[1]])
    np.testing.assert_allclose(high, [raw_high[0], g_max])

    out = plots.plot_curves(table, tmp_path / "curves.png")
    (poly,) = figures[0].axes[0].collections  # the band drawn
    y = poly.get_paths()[0].vertices[:, 1]
    assert y.min() == pytest.approx(0.0) and y.max() == pytest.approx(g_max)
    rows = _csv_rows(out.with_suffix(".csv"))
    lows = [float(r["mean"]) - float(r["ci95_half_width"]) for r in rows]
    highs = [float(r["mean"]) + float(r["ci95_half_width"]) for r in rows]
    assert lows[0] < 0 and lows[0] == pytest.approx(raw_low[0])
    assert highs[1] > g_max and highs[1] == pytest.approx(raw_high[1])


def test_final_error_bars_are_clipped(tmp_path, figures):
    runs = [
        _fake_run(tmp_path, "a", "D", 3, [0.0, 0.0], seed=0),
        _fake_run(tmp_path, "b", "D", 3, [0.0, 1.0], seed=1),
    ]
    table = final_table(load_runs(runs, x="n_req"), "n_req")
    assert table["D"]["mean"][0] - table["D"]["ci"][0] < 0
    out = plots.plot_final(table, tmp_path / "final.png", "n_req")
    bars = [c for c in figures[0].axes[0].collections if len(c.get_segments())]
    (segment,) = bars[0].get_segments()
    assert segment[:, 1].min() == pytest.approx(0.0)
    assert segment[:, 1].max() == pytest.approx(0.5 + table["D"]["ci"][0])
    (row,) = _csv_rows(out.with_suffix(".csv"))
    assert float(row["mean"]) - float(row["ci95_half_width"]) < 0  # raw in the CSV


def test_smoothing_is_stated_and_raw_values_kept(tmp_path, figures):
    run = _fake_run(tmp_path, "demo", "max-critic", 3, [0.0, 2.0, 4.0, 6.0])
    result = plots.make_curves([run], run / "learning_curve.png", smooth=2)
    assert result.png == run / "learning_curve.png" and result.png.exists()
    legend = _legend(figures[0])
    assert "max-critic (n=1, 2-generation moving mean)" in legend
    assert "max G" in legend
    (max_line,) = [line for line in figures[0].axes[0].lines if line.get_label() == "max G"]
    assert set(max_line.get_ydata()) == {10.0} and max_line.get_linestyle() == "--"
    rows = _csv_rows(result.csv)
    assert list(rows[0]) == plots.CURVE_COLUMNS
    assert [float(r["mean"]) for r in rows] == [0.0, 1.0, 3.0, 5.0]
    assert [float(r["raw_mean"]) for r in rows] == [0.0, 2.0, 4.0, 6.0]
    assert {r["smooth_window"] for r in rows} == {"2"}
    # unsmoothed: no note in the legend
    plots.make_curves([run], tmp_path / "raw.png")
    assert "max-critic (n=1)" in _legend(figures[1])


def test_default_out(tmp_path):
    assert plots.default_out(["runs/a"]) == Path("runs/a/curves.png")
    assert plots.default_out(["runs/a", "runs/demo"]) == Path("runs/curves.png")
    assert plots.default_out(["runs/a", "runs/demo"], "n_req") == Path("runs/final_n_req.png")
    assert plots.default_out(["x/s/a", "x/t/b/"]) == Path("x/curves.png")
    assert plots.default_out(["a", "b"]) == Path("curves.png")
    assert (
        plots.default_out([tmp_path / "r" / "a", tmp_path / "r" / "b"])
        == tmp_path / "r" / "curves.png"
    )


def test_default_title_and_output(tmp_path, figures):
    runs = [
        _fake_run(tmp_path, "a", "D", 3, [1.0], generations=2000, seed=0),
        _fake_run(tmp_path, "b", "max-critic", 3, [2.0], generations=2000, seed=1),
    ]
    title = "15 rovers, n_req 3, ideal motion, 2000 generations"
    assert plots.default_title(load_runs(runs)) == title
    result = plots.make_curves(runs)
    assert result.png == tmp_path / "curves.png" and result.csv.exists()
    assert figures[0].axes[0].get_title() == title
    mixed = runs + [_fake_run(tmp_path, "c", "D", 4, [1.0], generations=300, motion="physics")]
    assert plots.default_title(load_runs(mixed)) == "15 rovers"
    plots.make_curves(runs, tmp_path / "t.png", title="mine")
    assert figures[1].axes[0].get_title() == "mine"


def test_messages_name_runs_cut_to_the_shortest(tmp_path):
    runs = [
        _fake_run(tmp_path, "a", "max-critic", 3, [1.0] * 5, seed=0),
        _fake_run(tmp_path, "b", "max-critic", 3, [1.0] * 3, seed=1),  # unfinished
    ]
    result = plots.make_curves(runs, tmp_path / "c.png")
    assert result.messages == ["max-critic: 2 runs cut to the shortest, 3 generations (longest 5)"]
    assert len(_csv_rows(result.csv)) == 3


def test_final_numbers_by_field(tmp_path, figures):
    runs = [
        _fake_run(tmp_path, "a", "D", 3, [0.0, 4.0]),
        _fake_run(tmp_path, "b", "D", 3, [0.0, 6.0], seed=1),
        _fake_run(tmp_path, "c", "D", 5, [0.0, 1.0]),
    ]
    table = final_table(load_runs(runs, x="n_req"), "n_req", last=1)
    assert list(table) == ["D"]  # the x field does not split groups
    np.testing.assert_allclose(table["D"]["x"], [3, 5])
    np.testing.assert_allclose(table["D"]["mean"], [5.0, 1.0])
    mean, ci, n = mean_ci(np.array([4.0, 6.0]))
    assert table["D"]["ci"][0] == ci == pytest.approx(12.706 * np.sqrt(2) / np.sqrt(2))
    result = plots.make_final(runs, "n_req", last=2)
    assert result.png == tmp_path / "final_n_req.png" and result.png.exists()
    assert figures[0].axes[0].get_ylabel() == "Final score: G, mean of the last 2 generations"
    rows = _csv_rows(result.csv)
    assert list(rows[0]) == ["group", "n_req", "mean", "ci95_half_width", "n"]
    assert [(r["n_req"], r["mean"], r["n"]) for r in rows] == [("3", "2.5", "2"), ("5", "0.5", "1")]


def test_final_against_a_field_that_is_not_a_number_is_a_one_line_error(tmp_path, capsys):
    from physrover.cli import main

    runs = [_fake_run(tmp_path, "a", "D", 3, [1.0]), _fake_run(tmp_path, "b", "G", 3, [2.0])]
    with pytest.raises(ConfigError, match="method: --final draws .* against a number, and "
                       "method is 'D'; --by method"):  # fmt: skip
        final_table(load_runs(runs, x="method"), "method")
    assert main(["curves", str(tmp_path), "--final", "method"]) == 2  # before: a traceback
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("physrover: error: method: --final"), err
    assert not (tmp_path / "final_method.png").exists()


def test_a_whole_number_field_gets_whole_ticks(tmp_path, figures):
    runs = [_fake_run(tmp_path, "a", "D", 3, [1.0]), _fake_run(tmp_path, "b", "D", 4, [2.0])]
    plots.make_final(runs, "n_req", tmp_path / "final.png")
    ticks = [t for t in figures[0].axes[0].get_xticks() if 3 <= t <= 4]
    assert ticks == [3, 4]  # before: 3.0, 3.2, 3.4, ...


def test_a_short_run_gets_whole_generation_ticks(tmp_path, figures):
    runs = [_fake_run(tmp_path, "a", "D", 3, [1.0, 2.0, 2.0, 3.0, 1.0])]
    plots.make_curves(runs, tmp_path / "short.png")
    ticks = [t for t in figures[0].axes[0].get_xticks() if 1 <= t <= 5]
    assert ticks and all(t == round(t) for t in ticks)  # before: 1.0, 1.5, 2.0, ...


def test_the_demo_legend_stays_inside_the_axes(tmp_path, figures):
    # One run, smoothed: "max-critic (n=1, 20-generation moving mean)" and "max G". Put
    # beside the axes, it widened the figure by a third of white.
    runs = [_fake_run(tmp_path, "demo", "max-critic", 3, [float(g % 7) for g in range(40)])]
    plots.make_curves(runs, tmp_path / "demo.png", smooth=20)
    fig = figures[0]
    assert max(map(len, _legend(fig))) == len("max-critic (n=1, 20-generation moving mean)")
    legend, axes = fig.axes[0].get_legend().get_window_extent(), fig.axes[0].get_window_extent()
    assert legend.x1 <= axes.x1 and tuple(fig.get_size_inches()) == (6.4, 4.2)


def test_many_groups_keep_apart_and_keep_off_the_curves(tmp_path, figures):
    runs = [_fake_run(tmp_path, f"r{i}", "D", 3, [float(i)], poi_ring_radius=10.0 + i)
            for i in range(12)]  # fmt: skip
    plots.make_curves(runs, tmp_path / "many.png")
    ax = figures[0].axes[0]
    colours = [tuple(line.get_color()) if not isinstance(line.get_color(), str)
               else line.get_color() for line in ax.get_lines()[:12]]  # fmt: skip
    assert len(set(colours)) == 12  # before: the cycle of 10 repeated
    legend = ax.get_legend()
    box, axes_box = legend.get_window_extent(), ax.get_window_extent()
    assert box.x0 >= axes_box.x1  # beside the axes, not over the curves


def test_a_few_long_legend_entries_stay_inside_the_figure(tmp_path, figures):
    # Two groups whose names list every varied field: inside the axes the legend ran
    # past the figure's left edge, its entries cut off.
    fields = {"trajectory_batch": 8, "trajectory_batches": 4, "trajectory_hidden": 16}
    runs = [_fake_run(tmp_path, "a", "max-critic", 5, [1.0, 2.0]),
            _fake_run(tmp_path, "b", "recurrent-max-critic", 5, [1.0, 3.0], critic_hidden=40,
                      **fields)]  # fmt: skip
    plots.make_curves(runs, tmp_path / "long.png", smooth=2)
    fig = figures[0]
    assert max(map(len, _legend(fig))) > 100
    box = fig.axes[0].get_legend().get_window_extent()
    assert box.x0 >= 0 and box.x1 <= fig.bbox.x1 + 1


def test_a_trainer_run_is_not_grouped_by_the_ccea_generations(tmp_path):
    ccea = _fake_run(tmp_path, "ccea", "max-critic", 3, [1.0], generations=300)
    mappo = _fake_run(tmp_path, "mappo", "mappo", 3, [1.0], generations=777)
    other = _fake_run(tmp_path, "mappo2", "mappo", 3, [2.0], generations=5, seed=1)
    for run in (mappo, other):  # a trainer's metrics also count episodes
        (run / "metrics.csv").write_text(
            ",".join([*stats_header(), "episodes", "env_steps"]) + "\n1,1,0,0,0,0,32,800\n"
        )
    groups = {run.path.name: run.group for run in load_runs([ccea, mappo, other])}
    assert groups == {"ccea": "max-critic", "mappo": "mappo", "mappo2": "mappo"}


def test_a_method_keeps_its_colour_across_figures():
    from physrover.core.registry import FITNESS_METHODS as METHODS

    assert set(plots.METHOD_COLOURS) == set(METHODS)
    assert len(set(plots.METHOD_COLOURS.values())) == len(METHODS)
    four = plots.group_colours(["D", "average", "max-critic", "mean-critic"])
    three = plots.group_colours(["average", "max-critic", "mean-critic"])
    assert all(three[m] == four[m] for m in three)
    # labels that are not bare method names fall back to the axes' colour cycle
    assert plots.group_colours(["D ideal", "D physics"]) == {"D ideal": None, "D physics": None}
    # ... unless each names its method and no two groups share one
    methods = {"D n_req=4": "D", "max-critic n_req=4": "max-critic"}
    assert plots.group_colours(methods, methods) == {"D n_req=4": "C0", "max-critic n_req=4": "C2"}
    shared = {"D n_req=3": "D", "D n_req=4": "D", "max-critic n_req=4": "max-critic"}
    assert set(plots.group_colours(shared, shared).values()) == {None}


def test_band_of_a_single_run_is_nan():
    low, high = plots.band(np.array([1.0, 2.0]), np.array([math.nan, math.nan]), 10.0)
    assert np.isnan(low).all() and np.isnan(high).all()


def test_episodes_axis_counts_each_methods_training_episodes(tmp_path):
    # k = 50: D plays 50 training episodes a generation, the average 10 x 50, the hall of
    # fame R x 50 (R = 15); the champion's evaluation episodes do not count.
    runs = [
        _fake_run(tmp_path, "d", "D", 3, [1.0, 2.0]),
        _fake_run(tmp_path, "a", "average", 3, [1.0, 2.0]),
        _fake_run(tmp_path, "h", "hall-of-fame", 3, [1.0, 2.0]),
    ]
    table = curve_table(load_runs(runs))
    assert table["D"]["episodes"].tolist() == [50, 100]
    assert table["average"]["episodes"].tolist() == [500, 1000]
    assert table["hall-of-fame"]["episodes"].tolist() == [750, 1500]
    plot = plots.make_curves(runs, tmp_path / "by_episodes.png", x="episodes")
    rows = _csv_rows(plot.csv)
    assert [r["episodes"] for r in rows if r["group"] == "average"] == ["500", "1000"]
    with pytest.raises(ConfigError, match="--x"):
        plots.plot_curves(table, tmp_path / "bad.png", x="seconds")


def test_an_episodes_column_in_the_metrics_is_used_as_is(tmp_path):
    run = _fake_run(tmp_path, "m", "D", 3, [1.0, 2.0])
    text = (run / "metrics.csv").read_text().splitlines()
    text[0] += ",episodes"
    text[1] += ",32"
    text[2] += ",64"
    (run / "metrics.csv").write_text("\n".join(text) + "\n")
    assert load_runs([run])[0].episodes.tolist() == [32, 64]


def test_a_just_started_gradient_based_run_loads_with_no_rows(tmp_path):
    # A sweep's trainer run that has written no metrics row yet (its header only) loads
    # as an empty curve; it used to fall through to the CCEA's episodes per generation,
    # which have no meaning for MADDPG (KeyError: unknown fitness method 'maddpg').
    config = RunConfig().with_overrides({"method": "maddpg"})
    prepare_run_dir(tmp_path / "new", config)
    (run,) = load_runs([tmp_path / "new"])
    assert run.eval_G.size == 0 and run.episodes.size == 0


def test_runs_are_grouped_by_the_fields_of_every_table(tmp_path):
    # Runs that differ in a [physics] field and in the scenario's kind are grouped by them.
    from physrover.config import RunConfig
    from physrover.experiment.store import prepare_run_dir

    dirs = []
    for name, overrides in (("a", {"collisions": False}), ("b", {"scenario": "ring-random"})):
        config = RunConfig().with_overrides({"motion": "physics", **overrides})
        prepare_run_dir(tmp_path / name, config)
        (tmp_path / name / "metrics.csv").write_text(
            "generation,eval_G,train_G_mean,fitness_mean,critic_loss,wall_seconds\n"
            "1,1,0,0,nan,0.1\n"
        )
        dirs.append(tmp_path / name)
    runs = plots.load_runs(dirs)
    assert runs[0].fields["collisions"] is False and runs[1].fields["scenario"] == "ring-random"
    assert [r.group for r in runs] == [
        "max-critic collisions=false scenario=ring",
        "max-critic collisions=true scenario=ring-random",
    ]


def test_runs_differing_in_the_physical_integrator_are_kept_apart(tmp_path):
    # "compiled" changes trajectories with walls or obstacles, so the integrator is an
    # experiment field like any other, not bookkeeping.
    from physrover.experiment.store import prepare_run_dir

    dirs = []
    for integrator in ("auto", "compiled"):
        config = RunConfig().with_overrides({"motion": "physics", "integrator": integrator})
        prepare_run_dir(tmp_path / integrator, config)
        dirs.append(tmp_path / integrator)
    assert [r.group for r in plots.load_runs(dirs)] == [
        "max-critic integrator=auto",
        "max-critic integrator=compiled",
    ]


def test_a_trainers_seed_and_bookkeeping_do_not_split_groups():
    from physrover.analysis.curve_data import differing_fields

    fields = [
        {"method": "maddpg", "n_req": 1, "maddpg.seed": 0, "maddpg.checkpoint_every": 100,
         "maddpg.warmup_actions": "uniform"},
        {"method": "maddpg", "n_req": 1, "maddpg.seed": 1, "maddpg.checkpoint_every": 50,
         "maddpg.warmup_actions": "uniform"},
        {"method": "maddpg", "n_req": 1, "maddpg.seed": 0, "maddpg.checkpoint_every": 100,
         "maddpg.warmup_actions": "policy"},
    ]  # fmt: skip
    assert differing_fields(fields) == ["maddpg.warmup_actions"]


def test_a_legend_names_its_rows_generations_or_iterations():
    # A gradient-based trainer's metrics rows are iterations, a CCEA's generations.
    cols = {"n": 3, "smooth": 20}
    assert plots.curve_legend("mappo", cols | {"method": "mappo"}) == (
        "mappo (n=3, 20-iteration moving mean)"
    )
    assert plots.curve_legend("max-critic", cols | {"method": "max-critic"}) == (
        "max-critic (n=3, 20-generation moving mean)"
    )
    assert plots.curve_legend("D", {"n": 1, "smooth": 1, "method": "D"}) == "D (n=1)"
    assert plots.row_unit(["mappo", "maddpg"]) == "iteration"
    assert plots.row_unit(["mappo", "max-critic"]) == plots.row_unit([]) == "generation"


def test_a_trainer_s_curves_count_iterations_on_their_axis(tmp_path, figures):
    table = {"mappo": {"method": "mappo", "n": 1, "generation": np.array([1, 2]),
                       "mean": np.array([1.0, 2.0]), "ci": np.zeros(2), "g_max": 10.0}}  # fmt: skip
    plots.plot_curves(table, tmp_path / "mappo.png")
    assert figures[-1].axes[0].get_xlabel() == "Iteration"
    table["D"] = table["mappo"] | {"method": "D"}  # a mix: the CCEA's word
    plots.plot_curves(table, tmp_path / "both.png")
    assert figures[-1].axes[0].get_xlabel() == "Generation"


@pytest.mark.parametrize("name", ["fig7_long_final_vs_nreq.csv", "fig4-6_long_curves_nreq5.csv",
                                  "marl_curves_nreq3_250000.csv"])  # fmt: skip
def test_a_committed_figure_redraws_from_its_csv_to_the_same_numbers(name, tmp_path):
    """`physrover curves FILE.csv` draws a committed figure again from its numbers (its runs
    are long gone): the table read back is the one written, byte for byte."""
    import shutil

    from physrover.analysis.redraw import read_table
    from physrover.cli.main import main

    source = Path(__file__).parent.parent / "experiments" / "results" / name
    copy = tmp_path / name
    shutil.copy(source, copy)
    assert main(["curves", str(copy)]) == 0
    assert copy.read_bytes() == source.read_bytes()
    assert copy.with_suffix(".png").stat().st_size > 10_000
    table = read_table(source)
    assert len(table) >= 2 and all(len(cols["mean"]) == len(cols["ci"]) for cols in table.values())


def test_a_csv_physrover_did_not_write_is_refused_in_one_line(tmp_path, capsys):
    from physrover.cli.main import main

    other = tmp_path / "other.csv"
    other.write_text("a,b\n1,2\n")
    assert main(["curves", str(other)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "not a CSV that physrover curves or results wrote" in err[0]
    assert main(["curves", str(tmp_path / "missing.csv")]) == 2
