"""The CCEA on a team of agent classes (issue 33): each class's policies have its shape and
read its observations; runs train, resume bit-identically and render."""

import numpy as np
import pytest
from conftest import assert_same_run
from gymnasium.utils.env_checker import check_env
from oracles import policy_actions

from physrover.config import ConfigError, DomainConfig, LearnConfig, RunConfig
from physrover.envs import RoverEnv
from physrover.experiment.training import train
from physrover.learn.ccea import CCEA
from physrover.learn.classes import ClassLayouts, team_layout
from physrover.learn.policies import PolicyLayout

MIXED = """
[domain]
n_req = 1
steps = 20
scenario = { kind = "uniform", half_size = 5.0, min_separation = 1.0 }
[[agents]]
name = "rover"
count = 3
moves_with = ["uav"]
sensor = { kind = "lidar", radius = 4.0, empty = -1.0 }
[[agents]]
name = "uav"
count = 2
captures = false
action = "world"
influence_radius = 5.0
sensor = { kind = "lidar", sectors = 3, radius = 100.0, empty = -1.0 }
[learn]
population = 6
hidden = 5
"""


def test_each_class_has_its_own_policy_shape():
    domain = DomainConfig.from_toml(MIXED.split("[learn]")[0])
    layouts = team_layout(LearnConfig(hidden=5), domain)
    assert isinstance(layouts, ClassLayouts)
    assert [layout.n_in for layout in layouts.layouts] == [8, 6]
    sizes = [PolicyLayout(5, 8).size, PolicyLayout(5, 6).size]
    assert layouts.size == max(sizes) and layouts.n_in == 8
    genomes = layouts.init((5, 4), np.random.default_rng(0))
    # class by class, in order, from one generator: what PolicyLayout draws for each
    rng = np.random.default_rng(0)
    rover, uav = PolicyLayout(5, 8).init((3, 4), rng), PolicyLayout(5, 6).init((2, 4), rng)
    np.testing.assert_array_equal(genomes[:3], rover)
    np.testing.assert_array_equal(genomes[3:, :, : sizes[1]], uav)
    assert (genomes[3:, :, sizes[1] :] == 0).all()
    paper = team_layout(LearnConfig(hidden=5), DomainConfig())
    assert isinstance(paper, PolicyLayout)  # the paper's team


def test_a_class_policy_reads_its_own_columns():
    domain = DomainConfig.from_toml(MIXED.split("[learn]")[0])
    layouts = ClassLayouts(5, domain)
    rng = np.random.default_rng(1)
    genomes = layouts.init((5, 3), rng)[:, :1].transpose(1, 0, 2).repeat(2, 0)  # (E=2, R, P)
    obs = rng.normal(size=(2, 5, 8)).astype(np.float32)
    actions = layouts.act(genomes, obs)
    for rows, layout in zip(layouts.rows, layouts.layouts, strict=True):
        expected = policy_actions(genomes[:, rows, : layout.size], 5, obs[:, rows, : layout.n_in])
        np.testing.assert_allclose(actions[:, rows], expected, rtol=1e-5, atol=1e-6)
    # what a UAV policy gets in its padded columns does not matter
    obs[:, 3:, 6:] = 1e6
    np.testing.assert_array_equal(layouts.act(genomes, obs)[:, 3:], actions[:, 3:])


@pytest.mark.parametrize("seed", range(3))
def test_a_steering_team_plays_as_one_padded_network_bit_for_bit(seed):
    """The padded D -> H -> 2 networks give each class's own network's actions to the last
    bit, and the whole compiled episode plays what stepping the world with the classes'
    networks one by one plays."""
    from physrover.envs import RoverVectorEnv
    from physrover.learn.classes import MixedTeamPolicy
    from physrover.learn.rollout import TeamPolicy

    domain = DomainConfig.from_toml(MIXED.split("[learn]")[0])
    for activation in ("relu", "tanh"):
        layouts = ClassLayouts(5, domain, activation)
        rng = np.random.default_rng([seed, 2])
        genomes = layouts.init((5, 8), rng).transpose(1, 0, 2)  # (E=8, R, P)
        obs = rng.normal(size=(8, 5, 8)).astype(np.float32)
        obs[:, 3:, 6:] = 0.0  # a UAV's padded columns, as the world writes them
        team = layouts.prepare(genomes)
        assert isinstance(team, TeamPolicy) and team.n_in == 8
        by_class = MixedTeamPolicy(genomes, layouts)(obs)
        assert np.array_equal(team(obs).view(np.uint32), by_class.view(np.uint32))
        played = []
        for policy in (team, MixedTeamPolicy(genomes, layouts)):  # compiled, then a step loop
            env = RoverVectorEnv(8, config=domain)
            env.reset(seed=seed + 3)
            world = env.play_episode(policy)
            played.append((world.position_history.copy(), world.G.copy(), world.D.copy()))
        for compiled, looped in zip(*played, strict=True):
            assert np.array_equal(compiled, looped)
        assert played[0][1].shape == (8,)


def test_classes_of_one_width_are_played_as_laid_out():
    """Where every class reads as many inputs as the widest, the padded layout is the
    genomes' own: each entry where the general re-layout puts it."""
    domain = DomainConfig.from_toml(MIXED.split("[learn]")[0].replace(", sectors = 3", ""))
    layouts = ClassLayouts(5, domain)
    assert {layout.n_in for layout in layouts.layouts} == {layouts.n_in}
    genomes = layouts.init((5, 8), np.random.default_rng(0)).transpose(1, 0, 2)
    H, D = 5, layouts.n_in
    expected = np.zeros_like(genomes)
    for rows, layout in zip(layouts.rows, layouts.layouts, strict=True):
        w1 = layout.n_in * H
        expected[:, rows, :w1] = genomes[:, rows, :w1]
        expected[:, rows, D * H :] = genomes[:, rows, w1 : w1 + 3 * H + 2]
    assert np.array_equal(layouts.padded(genomes), expected)


def test_the_env_takes_classes_with_padded_observations():
    env = RoverEnv(config=DomainConfig.from_toml(MIXED.split("[learn]")[0]))
    assert env.observation_space.shape == (5, 8) and env.observation_space.low.min() == -1.0
    check_env(env, skip_render_check=True)
    obs, _ = env.reset(seed=0)
    assert (obs[3:, 6:] == 0).all()


@pytest.mark.parametrize(("method", "feedback"),
                         [("D", "D"), ("D", "ID-step"), ("max-critic", "ID")])  # fmt: skip
def test_the_ccea_trains_classes(method, feedback):
    config = RunConfig.from_toml(MIXED).with_overrides({"method": method,
                                                         "feedback": feedback})  # fmt: skip
    ccea = CCEA(config)
    assert ccea.genomes.shape == (5, 6, ccea.layout.size)
    for _ in range(3):
        stats = ccea.run_generation()
    assert stats.generation == 3 and np.isfinite(stats.eval_G)
    if feedback == "D":  # a UAV never counts toward a capture: D is 0, so is its fitness
        assert (ccea.fitness[3:] == 0).all()
    if method == "max-critic":  # each agent's critic sees its class's observations, padded
        buffer = ccea.method.critic.buffer
        pairs = buffer.items[:, : buffer.size]  # (R, n, ..., 8 observations + 2 actions)
        assert pairs.shape[-1] == 10 and buffer.size > 0
        assert (pairs[3:, ..., 6:8] == 0).all() and (pairs[:3, ..., 6:8] != 0).any()


def test_a_mixed_run_resumes_bit_identically_and_renders(tmp_path):
    config = RunConfig.from_toml(MIXED).with_overrides(
        {"method": "max-critic", "feedback": "ID-step", "checkpoint_every": 2}
    )
    full = train(config, tmp_path / "full", generations=4, progress=False)
    part = train(config, tmp_path / "part", generations=2, progress=False)
    train(None, part, resume=True, generations=4, progress=False)
    assert_same_run(full, part)
    from physrover.experiment.playback import record_run

    out, scores = record_run(full, tmp_path / "mixed.mp4", episodes=1)
    assert out.stat().st_size > 10_000 and len(scores) == 1


def test_gradient_trainers_refuse_classes():
    with pytest.raises(ConfigError, match="agents: mappo trains teams of the paper's rovers"):
        RunConfig.from_toml(MIXED.replace("[learn]", '[learn]\nmethod = "mappo"'))


def test_the_study_sweep_loads_with_every_run_valid(tmp_path):
    from physrover.experiment.sweep import Sweep

    sweep = Sweep.load("mixed-team")
    runs = list(sweep.runs(tmp_path))
    assert len(runs) == 6 * 2 * 10
    domain = sweep.base.domain
    assert [a.name for a in domain.agents] == ["rover", "uav"] and domain.n_rovers == 6
    assert all(p.visible_to == ("uav",) for p in domain.pois)


def test_pettingzoo_names_agents_by_class_with_their_own_spaces():
    pytest.importorskip("pettingzoo")
    from pettingzoo.test import parallel_api_test

    from physrover.envs.pettingzoo_env import RoverParallelEnv

    env = RoverParallelEnv(config=DomainConfig.from_toml(MIXED.split("[learn]")[0]))
    assert env.possible_agents == ["rover_0", "rover_1", "rover_2", "uav_0", "uav_1"]
    assert env.observation_space("rover_0").shape == (8,)
    assert env.observation_space("uav_1").shape == (6,)
    parallel_api_test(env, num_cycles=30)
    observations, _ = env.reset(seed=3)
    team, _ = RoverEnv(config=env.config).reset(seed=3)
    np.testing.assert_array_equal(observations["uav_0"], team[3, :6])
    np.testing.assert_array_equal(observations["rover_2"], team[2])


def test_torchrl_gives_each_class_a_group():
    pytest.importorskip("torchrl")
    import torch
    from torchrl.envs.utils import check_env_specs

    from physrover.envs import RoverTorchEnv

    domain = DomainConfig.from_toml(MIXED.split("[learn]")[0])
    env = RoverTorchEnv(3, domain)
    assert env.group_map == {"rover": ["rover_0", "rover_1", "rover_2"],
                             "uav": ["uav_0", "uav_1"]}  # fmt: skip
    check_env_specs(env, seed=0)
    env.set_seed(5)
    td = env.reset()
    assert td["rover", "observation"].shape == (3, 3, 8)
    assert td["uav", "observation"].shape == (3, 2, 6)
    # the same observations as the vector env's rows, unpadded; actions go to their agents
    from physrover.envs import RoverVectorEnv

    vector = RoverVectorEnv(3, config=domain)
    obs, _ = vector.reset(seed=5)
    np.testing.assert_array_equal(td["uav", "observation"].numpy(), obs[:, 3:, :6])
    actions = np.random.default_rng(0).uniform(-1, 1, (3, 5, 2)).astype(np.float32)
    td["rover", "action"] = torch.from_numpy(actions[:, :3])
    td["uav", "action"] = torch.from_numpy(actions[:, 3:])
    out = env.step(td)["next"]
    obs, *_ = vector.step(actions)
    np.testing.assert_array_equal(out["rover", "observation"].numpy(), obs[:, :3])
    assert out["uav", "reward"].shape == (3, 2, 1)
