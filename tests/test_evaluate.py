"""Cross-evaluation of a run's champion team (physrover evaluate)."""

import csv

import numpy as np
import pytest

from physrover import RoverEnv
from physrover.cli.main import main
from physrover.config import ConfigError, RunConfig
from physrover.experiment.evaluate import evaluate_run
from physrover.experiment.store import load_champions
from physrover.experiment.training import train
from physrover.learn.policies import PolicyLayout


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory):
    config = RunConfig().with_overrides(
        {
            "n_rovers": 4,
            "n_req": 1,
            "population": 8,
            "steps": 20,
            "method": "D",
            "seed": 3,
            "poi_ring_radius": 8.0,
        }  # captures in most episodes, not all
    )
    return train(config, tmp_path_factory.mktemp("eval") / "run", generations=15, progress=False)


def _single_env_G(run_dir, seeds, **changes):
    """Oracle: the champion team played episode by episode in the single env."""
    config = RunConfig.load(run_dir / "config.toml")
    _, genomes = load_champions(run_dir)
    env = RoverEnv(config=config.domain.replace(**changes))
    layout = PolicyLayout(config.learn.hidden, env.observation_space.shape[-1])
    scores = []
    for seed in seeds:
        obs, _ = env.reset(seed=seed)
        total, truncated = 0.0, False
        while not truncated:
            obs, reward, _, truncated, info = env.step(layout.act(genomes[None], obs[None])[0])
            total += reward
        assert total == info["G"]
        scores.append(total)
    return scores


@pytest.mark.parametrize("changes", [{}, {"motion": "physics"}, {"motion": "physics",
                                                                 "collisions": False}])  # fmt: skip
def test_evaluate_equals_the_single_env_episode_by_episode(run_dir, changes):
    result = evaluate_run(run_dir, episodes=6, seed=40, **changes)
    assert result.changes == changes
    np.testing.assert_array_equal(result.G, _single_env_G(run_dir, range(40, 46), **changes))
    assert 0 < result.G.sum() and len(set(result.G)) > 1  # a case that can tell seeds apart
    assert result.mean == pytest.approx(np.mean(result.G))


def test_evaluate_cli_writes_the_episodes(run_dir, tmp_path, capsys):
    out = tmp_path / "eval.csv"
    argv = ["evaluate", str(run_dir), "--episodes", "5", "--seed", "7", "--motion", "physics",
            "--no-collisions", "--out", str(out)]  # fmt: skip
    assert main(argv) == 0
    said = capsys.readouterr().out
    assert "motion=physics, collisions=False" in said and "over 5 episodes" in said
    rows = list(csv.DictReader(open(out)))
    assert [int(r["seed"]) for r in rows] == [7, 8, 9, 10, 11]
    expected = _single_env_G(run_dir, range(7, 12), motion="physics", collisions=False)
    assert [float(r["G"]) for r in rows] == expected
    with pytest.raises(ConfigError, match="episodes"):
        evaluate_run(run_dir, episodes=0)


def test_evaluate_plays_at_another_coupling(run_dir, tmp_path, capsys):
    """``--n-req`` (a champion trained at one coupling played at another, as issue 46's
    transfer from n_req 4 to 5): every episode as the single env plays it at that coupling;
    a coupling the team cannot have is a one-line error."""
    out = tmp_path / "eval.csv"
    argv = ["evaluate", str(run_dir), "--episodes", "6", "--seed", "40", "--n-req", "2",
            "--out", str(out)]  # fmt: skip
    assert main(argv) == 0
    assert "under n_req=2: mean G" in capsys.readouterr().out
    tight = [float(r["G"]) for r in csv.DictReader(open(out))]
    assert tight == _single_env_G(run_dir, range(40, 46), n_req=2)
    assert sum(tight) < evaluate_run(run_dir, episodes=6, seed=40).G.sum()  # 2 is harder
    assert main(["evaluate", str(run_dir), "--n-req", "5"]) == 2
    assert "n_req" in capsys.readouterr().err


@pytest.mark.parametrize("motion", ["ideal", "physics"])
def test_a_checkpoint_replays_the_runs_own_next_eval_G(tmp_path, motion):
    """The champion saved after generation g, played step by step in a gymnasium vector env
    from the evaluation teams' generators saved at that checkpoint, scores exactly the eval
    G the run logged for generation g + 1 (which training computed with its own, compiled,
    episode path)."""
    import json

    from physrover import RoverVectorEnv
    from physrover.envs.gymnasium_env import generator_from_state
    from physrover.experiment.store import read_metrics

    config = RunConfig().with_overrides(
        {
            "n_rovers": 4,
            "n_req": 1,
            "population": 6,
            "steps": 20,
            "method": "max-critic",
            "seed": 8,
            "poi_ring_radius": 5.0,
            "eval_episodes": 5,
            "checkpoint_every": 4,
            "motion": motion,
        }  # fmt: skip
    )
    run = train(config, tmp_path / "run", generations=4, progress=False)
    meta = json.loads((run / "state.json").read_text())
    _, champion = load_champions(run, 4)
    train(None, run, resume=True, generations=5, progress=False)
    logged = read_metrics(run / "metrics.csv")[4]["eval_G"]  # generation 5's row

    eval_states = meta["env_rng"][-5:]  # the last eval_episodes teams are the evaluation
    env = RoverVectorEnv(5, config=config.domain, fresh_teams=5)
    env.reset(seed=0)
    env.set_rng_states(eval_states)
    obs, info = env.reset()  # continues the restored generators
    layout = PolicyLayout(config.learn.hidden, env.single_observation_space.shape[-1])
    act = layout.prepare(np.broadcast_to(champion, (5, *champion.shape)))
    for _ in range(config.domain.steps):
        obs, _, _, _, info = env.step(act(obs))
    assert float(np.mean(info["G"])) == logged
    assert 0 < logged < sum(config.domain.poi_values)  # some captures, not every POI always
    assert generator_from_state(eval_states[0]).bit_generator.state == eval_states[0]


def test_motion_model_names_each_of_the_three_models():
    from physrover.experiment.evaluate import MOTION_MODELS, motion_model

    for name, changes in MOTION_MODELS.items():
        assert motion_model(changes["motion"], changes.get("collisions", True)) == name
    assert motion_model("ideal", False) == "ideal"  # collisions only matter under physics
