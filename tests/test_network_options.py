"""The policies' network options (``[learn] activation``, ``weight_init``): the lab's tanh
hidden layer and U(-1, 1) weights, against a numpy oracle; the paper's network unchanged."""

import numpy as np
import pytest
from oracles import policy_actions

from physrover.config import ConfigError, LearnConfig, RunConfig
from physrover.domain.world import RoverWorld
from physrover.learn.ccea import CCEA
from physrover.learn.policies import PolicyLayout
from physrover.learn.rollout import play_episode


@pytest.mark.parametrize("activation", ["relu", "tanh"])
def test_the_forward_pass_is_the_numpy_network(activation):
    rng = np.random.default_rng(1)
    layout = PolicyLayout(7, 8, activation=activation, weight_init="uniform")
    genomes = layout.init((6, 5), rng)
    obs = rng.uniform(-3, 3, (6, 5, 8)).astype(np.float32)
    expected = policy_actions(genomes, 7, obs, activation)
    np.testing.assert_allclose(layout.act(genomes, obs), expected, rtol=1e-5, atol=2e-6)
    other = policy_actions(genomes, 7, obs, "tanh" if activation == "relu" else "relu")
    assert np.abs(layout.act(genomes, obs) - other).max() > 0.1  # the option changes it


def test_a_picking_policy_takes_the_largest_output_of_its_tanh_network():
    rng = np.random.default_rng(2)
    layout = PolicyLayout(6, 5, n_out=4, activation="tanh")
    genomes = layout.init((3, 4), rng)
    obs = rng.uniform(-2, 2, (3, 4, 5)).astype(np.float32)
    b = layout.bounds
    w1 = genomes[..., b[0] : b[1]].reshape(3, 4, 5, 6)
    w2 = genomes[..., b[2] : b[3]].reshape(3, 4, 6, 4)
    h = np.tanh(np.einsum("eri,eriu->eru", obs, w1) + genomes[..., b[1] : b[2]])
    z = np.einsum("eru,eruj->erj", h, w2) + genomes[..., b[3] : b[4]]
    choice = z.argmax(-1)
    np.testing.assert_array_equal(layout.act(genomes, obs)[..., 0], -1 + (2 * choice + 1) / 4)


def test_weights_start_in_their_ranges():
    rng = np.random.default_rng(0)
    fan_in = PolicyLayout(32, 8).init((15, 50), rng)
    uniform = PolicyLayout(32, 8, weight_init="uniform").init((15, 50), rng)
    assert np.abs(fan_in[..., : 8 * 32]).max() <= 1 / np.sqrt(8)
    assert np.abs(fan_in[..., -2:]).max() <= 1 / np.sqrt(32)
    assert np.abs(uniform).max() <= 1.0 and np.abs(uniform).max() > 0.99
    assert abs(float(uniform.mean())) < 0.01 and abs(float(uniform.std()) - 1 / np.sqrt(3)) < 0.01


def test_the_compiled_episode_plays_a_tanh_network_as_the_step_loop():
    config = RunConfig().with_overrides({"n_req": 1, "steps": 20, "activation": "tanh"})
    layout = PolicyLayout(7, 8, activation="tanh", weight_init="uniform")
    policy = layout.prepare(layout.init((4, 15), np.random.default_rng(3)))
    worlds = []
    for compiled in (True, False):
        world = RoverWorld(config.domain, 4)
        obs = world.reset([np.random.default_rng([5, e]) for e in range(4)])
        if compiled:
            play_episode(world, obs, policy, True)
        else:
            for _ in range(config.domain.steps):
                obs = world.step(policy(obs))
        worlds.append(world)
    for name in ("observations", "actions", "position_history"):
        np.testing.assert_array_equal(getattr(worlds[0], name), getattr(worlds[1], name))


def test_the_ccea_trains_the_labs_network_reproducibly_and_refuses_unknown_ones():
    fields = {"n_req": 1, "n_rovers": 4, "population": 6, "method": "D", "seed": 2,
              "activation": "tanh", "weight_init": "uniform"}  # fmt: skip
    runs = []
    for _ in range(2):
        ccea = CCEA(RunConfig().with_overrides(fields))
        runs.append([ccea.run_generation().eval_G for _ in range(3)])
        assert np.abs(ccea.genomes).max() > 0.9  # U(-1, 1), then mutated
    assert runs[0] == runs[1]
    paper = CCEA(RunConfig().with_overrides({**fields, "activation": "relu",
                                             "weight_init": "fan-in"}))  # fmt: skip
    assert not np.array_equal(paper.genomes, ccea.genomes)
    with pytest.raises(ConfigError, match="activation: "):
        LearnConfig(activation="sigmoid")
    with pytest.raises(ConfigError, match="weight_init: "):
        LearnConfig(weight_init="xavier")
