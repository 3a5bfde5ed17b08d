"""The CCEA end to end: it learns an easy task, resumes bit-identically, and the CLI."""

import numpy as np
import pytest
from conftest import assert_same_run, comparable_rows

from physrover.cli.main import main
from physrover.config import ConfigError, RunConfig
from physrover.experiment.store import read_metrics
from physrover.experiment.training import train
from physrover.learn.ccea import CCEA

EASY = dict(n_rovers=3, n_req=1, population=20, steps=50)


def test_ccea_learns_an_easy_task():
    # 3 rovers, a single rover captures (n_req = 1): the untrained champion scores 0, after
    # 200 generations with D the champion team takes most of the 10 points.
    ccea = CCEA(RunConfig().with_overrides({**EASY, "method": "D", "seed": 0}))
    curve = [ccea.run_generation().eval_G for _ in range(200)]
    assert np.mean(curve[:5]) == 0.0
    assert np.mean(curve[-20:]) >= 6.0


@pytest.mark.parametrize(
    ("method", "rounds"),
    [("average", 3), ("leniency", 3), ("G", 1), ("mean-critic-inexact", 1), ("hall-of-fame", 3)],
)
def test_every_method_runs_a_generation(method, rounds):
    samples = {"n_samples": 3} if method in ("average", "leniency") else {}  # [sampled]
    ccea = CCEA(RunConfig().with_overrides({**EASY, "method": method, **samples}))
    stats = ccea.run_generation()
    assert np.isfinite(stats.fitness_mean)
    assert ccea.env.num_envs == rounds * 20 + 10


def test_hall_of_fame_tests_each_policy_with_the_best_team():
    ccea = CCEA(RunConfig().with_overrides({**EASY, "method": "hall-of-fame", "seed": 1}))
    hof = ccea.method
    seen = {}
    real = ccea.rollout

    def spy(index):
        seen["index"] = index
        return real(index)

    ccea.rollout = spy
    for _ in range(30):
        before = hof.genomes.copy(), hof.score
        evaluated = ccea.champion_genomes()
        stats = ccea.run_generation()
        if stats.eval_G > before[1]:  # the evaluated champion becomes the hall of fame
            np.testing.assert_array_equal(hof.genomes, evaluated)
            assert hof.score == stats.eval_G
        else:
            np.testing.assert_array_equal(hof.genomes, before[0])
    # Round q tests rover q's 20 policies; every other rover plays the hall-of-fame slot 20.
    teams = seen["index"][:60].reshape(3, 20, 3)
    for q in range(3):
        assert sorted(teams[q, :, q]) == list(range(20))
        assert np.all(np.delete(teams[q], q, axis=1) == 20)
    assert hof.score > 0


def _assert_each_policy_plays_once_with_its_own_d(ccea):
    """Run a generation of ``ccea`` (method D): each rover's k policies play once each in
    the k training teams, and each policy's fitness is its own episode's D."""
    seen = {}

    def spy(index):
        seen["index"] = index
        return real(index)

    real = ccea.rollout
    ccea.rollout = spy
    ccea.run_generation()
    k, n_rovers = ccea.fitness.shape[1], ccea.fitness.shape[0]
    teams = seen["index"][:k]  # training teams; the rest are the champion's
    D = ccea.env.world.D[:k]
    for r in range(n_rovers):
        assert sorted(teams[:, r]) == list(range(k))
        np.testing.assert_array_equal(ccea.fitness[r, teams[:, r]], D[:, r])


def test_each_policy_plays_once_per_round_and_fitness_is_its_own_feedback():
    ccea = CCEA(RunConfig().with_overrides({**EASY, "method": "D", "n_rovers": 4, "n_req": 2}))
    _assert_each_policy_plays_once_with_its_own_d(ccea)


@pytest.mark.parametrize(
    "method",
    ["max-critic", "mean-critic", "hall-of-fame", "step-input", "ensemble", "trained-output"],
)
def test_resume_is_bit_identical(tmp_path, method):
    step_input = method == "step-input"  # the max critic that also sees the step
    ensemble = 3 if method == "ensemble" else 1  # an optimistic ensemble of 3 max critics
    critic = {
        "critic_output_weights": "trained" if method == "trained-output" else "fixed",
        "critic_step_input": step_input,
        "critic_ensemble": ensemble,
        "critic_optimism": 1.0 if ensemble > 1 else 0.0,
        "replay_pairs": 700,
        "critic_optimizer": "adam",
        "critic_lr": 1e-3,
    }
    config = RunConfig().with_overrides(
        {
            **EASY,
            "method": method if "critic" in method or method == "hall-of-fame" else "max-critic",
            "checkpoint_every": 3,
            "seed": 5,
            **(critic if method != "hall-of-fame" else {}),
        }
    )
    full = train(config, tmp_path / "full", generations=8, progress=False)
    part = train(config, tmp_path / "part", generations=5, progress=False)
    train(None, part, resume=True, generations=8, progress=False)
    assert_same_run(full, part)
    assert len(read_metrics(full / "metrics.csv")) == 8


def test_resume_after_a_crash_drops_rows_past_the_checkpoint(tmp_path):
    config = RunConfig().with_overrides({**EASY, "method": "D", "checkpoint_every": 3})
    full = train(config, tmp_path / "full", generations=7, progress=False)
    crashed = tmp_path / "crashed"

    class Crash(Exception):
        pass

    def crash_at_5(stats):
        if stats.generation == 5:  # rows 1-5 written, last checkpoint after generation 3
            raise Crash

    with pytest.raises(Crash):
        train(config, crashed, generations=7, progress=False, on_generation=crash_at_5)
    assert len(read_metrics(crashed / "metrics.csv")) == 5
    train(None, crashed, resume=True, progress=False)
    assert comparable_rows(read_metrics(crashed / "metrics.csv")) == comparable_rows(
        read_metrics(full / "metrics.csv")
    )


def test_metrics_columns_and_config_round_trip(tmp_path):
    config = RunConfig().with_overrides({**EASY, "method": "D"})
    out = train(config, tmp_path / "run", generations=2, progress=False)
    header = (out / "metrics.csv").read_text().splitlines()[0]
    assert header == "generation,eval_G,train_G_mean,fitness_mean,critic_loss,wall_seconds"
    assert RunConfig.load(out / "config.toml") == config.with_overrides({"generations": 2})
    assert (out / "champions" / "gen_000002.npy").exists()


def test_set_resolves_names_across_tables():
    config = RunConfig().with_overrides({"n_rovers": 6, "population": 20, "n_req": 4})
    assert (config.domain.n_rovers, config.learn.population, config.domain.n_req) == (6, 20, 4)
    with pytest.raises(ConfigError, match="popsize: unknown config field"):
        RunConfig().with_overrides({"popsize": 3})


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["train", "--method", "magic"], "method: unknown fitness method 'magic'"),
        (["train", "--config", "missing.toml"], "missing.toml: cannot read"),
        (["train", "--set", "n_req=99"], "n_req: must be in [1, n_rovers=15]"),
        (["train", "--set", "colour=red"], "colour: unknown config field"),
        (["train", "--resume", "nowhere"], "nowhere is not a run directory"),
    ],
)
def test_cli_errors_are_one_line(argv, message, capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("physrover: error: ") and message in err


def test_cli_train_then_refuses_a_non_empty_dir_and_resumes(tmp_path, capsys):
    out = tmp_path / "run"
    args = [
        "train",
        "--set",
        "n_rovers=3",
        "--set",
        "n_req=1",
        "--set",
        "population=4",
        "--method",
        "D",
        "--generations",
        "2",
        "--out",
        str(out),
        "--quiet",
    ]
    assert main(args) == 0
    assert main(args) == 2
    assert "not empty; use --resume" in capsys.readouterr().err
    assert main(["train", "--resume", str(out), "--generations", "3", "--quiet"]) == 0
    assert len(read_metrics(out / "metrics.csv")) == 3


def test_the_old_engine_variable_is_noted_not_obeyed(capsys, monkeypatch):
    monkeypatch.setenv("PHYSROVER_ENGINE", "numpy")
    assert main(["methods"]) == 0
    assert "PHYSROVER_ENGINE is no longer read" in capsys.readouterr().err


@pytest.mark.parametrize("motion", ["ideal", "physics"])
def test_a_hundred_rover_team_trains_and_its_fitness_is_each_rovers_own_d(motion):
    """Big teams are first-class: a CCEA generation of 100 rovers (10 policies each) under
    both motion models, each policy's fitness its own episode's D."""
    config = RunConfig().with_overrides({
        "n_rovers": 100, "n_req": 3, "population": 10, "steps": 20, "method": "D",
        "motion": motion, "scenario": {"kind": "ring", "spawn_density": 2.0},
    })  # fmt: skip
    _assert_each_policy_plays_once_with_its_own_d(CCEA(config))


def test_a_hundred_rover_max_critic_run_resumes_bit_identically(tmp_path):
    config = RunConfig().with_overrides({
        "n_rovers": 100, "n_req": 3, "population": 6, "steps": 15, "method": "max-critic",
        "checkpoint_every": 2, "replay_pairs": 2000, "eval_episodes": 2,
    })  # fmt: skip
    full = train(config, tmp_path / "full", generations=4, progress=False)
    part = train(config, tmp_path / "part", generations=3, progress=False)
    train(None, part, resume=True, generations=4, progress=False)
    assert_same_run(full, part)
