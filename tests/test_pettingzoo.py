"""The PettingZoo parallel env (physrover.marl): conformance, rewards, infos, errors."""

import subprocess
import sys

import numpy as np
import pytest

from physrover import RoverEnv
from physrover.config import ConfigError, DomainConfig
from physrover.envs import parallel_env
from physrover.envs.pettingzoo_env import MISSING_PETTINGZOO

SMALL = {"n_rovers": 3, "n_req": 2, "steps": 10}
# Rovers 0 and 1 on the first POI (15, 0), rover 2 at the origin: the POI is captured at
# reset, and rover 2 cannot come within d_cap = 4 of it in 10 steps of at most 1 unit, so
# D = 1 (the POI's value) for rovers 0 and 1 and 0 for rover 2.
ON_POI = {
    "rover_positions": [(15.0, 0.0), (15.0, 0.5), (0.0, 0.0)],
    "rover_headings": [0.0, 0.0, 0.0],
}


@pytest.fixture
def pettingzoo():
    return pytest.importorskip("pettingzoo")


def _random_actions(env, rng):
    """One seeded (2,) float32 action per live agent."""
    return {a: rng.uniform(-1, 1, 2).astype(np.float32) for a in env.agents}


def _episode(env, seed, options=None, action_seed=0):
    """Play an episode with seeded random actions: (rewards (T, R), final infos, actions)."""
    rng = np.random.default_rng(action_seed)
    env.reset(seed=seed, options=options)
    rewards, actions = [], []
    while env.agents:
        act = _random_actions(env, rng)
        _, rew, _, _, infos = env.step(act)
        rewards.append([rew[a] for a in env.possible_agents])
        actions.append(np.stack([act[a] for a in env.possible_agents]))
    return np.array(rewards), infos, actions


# PettingZoo's api tests probe reset(options={"options": 1}): ignored with a warning.
@pytest.mark.filterwarnings("ignore:ignoring unknown reset options 'options'")
def test_parallel_api(pettingzoo):
    from pettingzoo.test import parallel_api_test

    parallel_api_test(parallel_env(**SMALL), num_cycles=2 * SMALL["steps"])


def test_parallel_seed(pettingzoo):
    from pettingzoo.test import parallel_seed_test

    parallel_seed_test(lambda: parallel_env(**SMALL), num_cycles=2 * SMALL["steps"])


# Box(0, inf) is the observation space the sensor has (densities are unbounded above).
@pytest.mark.filterwarnings("ignore:Agent's maximum observation space value is infinity")
@pytest.mark.filterwarnings("ignore:ignoring unknown reset options 'options'")
def test_aec_api_through_parallel_to_aec(pettingzoo):
    from pettingzoo.test import api_test
    from pettingzoo.utils.conversions import parallel_to_aec

    api_test(parallel_to_aec(parallel_env(**SMALL)), num_cycles=2 * SMALL["steps"])


def test_spaces_agents_and_metadata(pettingzoo):
    env = parallel_env(n_rovers=4, n_req=2, steps=5)
    assert isinstance(env, pettingzoo.ParallelEnv)
    assert env.possible_agents == ["rover_0", "rover_1", "rover_2", "rover_3"]
    assert env.agents == []  # until reset
    obs_dim = RoverEnv(n_rovers=4).observation_space.shape[1]
    for agent in env.possible_agents:
        obs_space, act_space = env.observation_space(agent), env.action_space(agent)
        assert obs_space is env.observation_space(agent)
        assert act_space is env.action_space(agent)
        assert obs_space.shape == (obs_dim,) and obs_space.dtype == np.float32
        assert np.all(obs_space.low == 0) and np.all(obs_space.high == np.inf)
        assert act_space.shape == (2,) and act_space.dtype == np.float32
        assert np.all(act_space.low == -1) and np.all(act_space.high == 1)
    # One space per agent, so seeding one agent's space leaves the others' samples alone.
    assert env.action_space("rover_0") is not env.action_space("rover_1")
    assert env.metadata["name"] == "physrover_rover_v0"
    assert env.metadata["render_modes"] == ["rgb_array"]
    assert env.metadata["is_parallelizable"] is True
    assert env.metadata["render_fps"] == RoverEnv.metadata["render_fps"]
    obs, _ = env.reset(seed=0)
    assert env.state_space.shape == (4 * obs_dim,)
    np.testing.assert_array_equal(env.state(), np.concatenate([obs[a] for a in env.agents]))


def test_config_is_resolved_like_rover_env(pettingzoo):
    base = DomainConfig(n_rovers=5, n_req=2)
    assert parallel_env(base, steps=7).config == RoverEnv(base, steps=7).config
    mapping = {"n_rovers": 2}
    assert parallel_env(mapping, n_req=1).config == RoverEnv(mapping, n_req=1).config
    assert parallel_env(base).possible_agents[-1] == "rover_4"
    with pytest.raises(ConfigError):
        parallel_env(n_rover=3)


@pytest.mark.parametrize(
    "fields, options",
    [
        (SMALL, None),
        (SMALL, ON_POI),  # captured at reset: G >= 1
        ({"n_rovers": 3, "n_req": 1, "steps": 10, "poi_ring_radius": 3.0}, None),
    ],
    ids=["random-start", "on-poi", "easy-captures"],
)
def test_g_rewards_sum_to_final_g(pettingzoo, fields, options):
    env = parallel_env(**fields)
    rewards, infos, _ = _episode(env, seed=1, options=options)
    G = infos["rover_0"]["G"]
    assert rewards.shape == (fields["steps"], 3)
    np.testing.assert_allclose(rewards.sum(axis=0), [G] * 3)
    # Every agent gets the same team reward at every step.
    assert np.all(rewards == rewards[:, :1])
    if options is not None or fields.get("n_req") == 1:
        assert G > 0


@pytest.mark.parametrize("options", [None, ON_POI], ids=["random-start", "on-poi"])
def test_d_rewards_equal_rover_env_d(pettingzoo, options):
    env = parallel_env(reward="D", **SMALL)
    rewards, infos, actions = _episode(env, seed=3, options=options, action_seed=5)

    ref = RoverEnv(**SMALL)
    ref.reset(seed=3, options=options)
    for action in actions:
        *_, info = ref.step(action)
    assert np.all(rewards[:-1] == 0)
    np.testing.assert_array_equal(rewards[-1], info["D"])
    np.testing.assert_array_equal([infos[a]["D"] for a in env.possible_agents], info["D"])
    if options is not None:
        np.testing.assert_array_equal(info["D"], [1.0, 1.0, 0.0])


def test_observations_and_infos_match_rover_env(pettingzoo):
    env = parallel_env(**SMALL)
    ref = RoverEnv(**SMALL)
    obs, infos = env.reset(seed=7)
    ref_obs, ref_info = ref.reset(seed=7)
    rng = np.random.default_rng(0)
    for t in range(SMALL["steps"]):
        for i, agent in enumerate(env.possible_agents):
            np.testing.assert_array_equal(obs[agent], ref_obs[i])
            assert obs[agent].dtype == np.float32
            assert infos[agent]["G"] == ref_info["G"]
            np.testing.assert_array_equal(infos[agent]["position"], ref_info["rover_positions"][i])
            assert infos[agent]["position"].shape == (2,)
            assert infos[agent]["heading"] == ref_info["rover_headings"][i]
        action = rng.uniform(-1, 1, (3, 2))
        obs, rew, term, trunc, infos = env.step(dict(zip(env.possible_agents, action, strict=True)))
        ref_obs, ref_rew, _, ref_trunc, ref_info = ref.step(action)
        assert rew == dict.fromkeys(env.possible_agents, ref_rew)
        assert not any(term.values())
        assert trunc == dict.fromkeys(env.possible_agents, ref_trunc)
        assert ref_trunc == (t == SMALL["steps"] - 1)


def test_truncation_empties_agents_and_reset_revives(pettingzoo):
    env = parallel_env(**SMALL)
    env.reset(seed=0)
    zero = np.zeros(2, dtype=np.float32)
    for t in range(SMALL["steps"]):
        assert env.agents == env.possible_agents
        _, _, term, trunc, _ = env.step(dict.fromkeys(env.agents, zero))
        assert set(trunc) == set(term) == set(env.possible_agents)
        assert not any(term.values())
        assert all(trunc.values()) == (t == SMALL["steps"] - 1)
        assert any(trunc.values()) == all(trunc.values())
    assert env.agents == []
    with pytest.raises(RuntimeError, match="reset"):
        env.step({})
    env.reset()
    assert env.agents == env.possible_agents


def test_reset_seed_reproduces_and_options_pass_through(pettingzoo):
    env = parallel_env(**SMALL)
    first, _ = env.reset(seed=11)
    other, _ = env.reset(seed=12)
    again, _ = env.reset(seed=11)
    assert all(np.array_equal(first[a], again[a]) for a in env.possible_agents)
    assert not all(np.array_equal(first[a], other[a]) for a in env.possible_agents)
    _, infos = env.reset(seed=0, options=ON_POI)
    for agent, pos in zip(env.possible_agents, ON_POI["rover_positions"], strict=True):
        np.testing.assert_array_equal(infos[agent]["position"], pos)
        assert infos[agent]["heading"] == 0.0
    with pytest.warns(UserWarning, match="ignoring unknown reset options 'rover_position'"):
        env.reset(seed=0, options={"rover_position": ON_POI["rover_positions"]})


def test_unknown_reward_is_a_clear_error(pettingzoo):
    with pytest.raises(ValueError, match=r"reward: unknown credit signal 'L'.*known: D, G, D\+\+"):
        parallel_env(reward="L", **SMALL)


# One rover on the first POI, n_req 2: D is 0 for all, D++ credits the rover on the POI.
ALONE = {"rover_positions": [(15.0, 0.0), (0.0, 0.0), (0.0, 5.0)],
         "rover_headings": [0.0, 0.0, 0.0]}  # fmt: skip


def test_any_credit_signal_is_a_reward_at_the_last_step(pettingzoo):
    from physrover.core.registry import CREDITS

    env = parallel_env(reward="D++", **SMALL)
    rewards, _, _ = _episode(env, seed=3, options=ALONE, action_seed=5)
    assert not rewards[:-1].any()
    expected = CREDITS["D++"](env.env.world)[0]
    np.testing.assert_array_equal(rewards[-1], expected)
    assert expected[0] > 0 and not env.env.world.D.any()  # D++ credits what D cannot


def test_bad_actions_are_clear_errors(pettingzoo):
    env = parallel_env(**SMALL)
    env.reset(seed=0)
    zero = np.zeros(2, dtype=np.float32)
    with pytest.raises(ValueError, match=r"no action for rover_1, rover_2: step\(\) needs"):
        env.step({"rover_0": zero})
    with pytest.raises(ValueError, match=r"unknown agents 'rover_9'"):
        env.step({**dict.fromkeys(env.agents, zero), "rover_9": zero})
    with pytest.raises(ValueError, match=r"action of rover_2 must have shape \(2,\), got \(3,\)"):
        env.step({"rover_0": zero, "rover_1": zero, "rover_2": np.zeros(3)})
    # The refused steps did not advance the episode: it still has all its steps to go.
    n_steps = 0
    while env.agents:
        env.step(dict.fromkeys(env.agents, zero))
        n_steps += 1
    assert n_steps == SMALL["steps"]


def test_render_returns_the_rover_env_frame(pettingzoo):
    env = parallel_env(render_mode="rgb_array", **SMALL)
    env.reset(seed=0, options=ON_POI)
    env.step(dict.fromkeys(env.agents, np.array([0.5, 0.0], dtype=np.float32)))
    frame = env.render()
    assert frame.ndim == 3 and frame.shape[2] == 3 and frame.dtype == np.uint8
    np.testing.assert_array_equal(frame, env.env.render())
    assert frame.std() > 0  # a drawing, not a blank frame


def test_bad_render_mode_is_an_error(pettingzoo):
    with pytest.raises(ValueError, match="render_mode"):
        parallel_env(render_mode="human", **SMALL)


def test_missing_pettingzoo_is_a_clear_import_error(monkeypatch):
    monkeypatch.setitem(sys.modules, "pettingzoo", None)  # makes ``import pettingzoo`` fail
    with pytest.raises(ImportError, match=r"pip install 'physrover\[marl\]'"):
        parallel_env(**SMALL)


def test_marl_imports_without_pettingzoo():
    code = (
        "import sys; sys.modules['pettingzoo'] = None\n"
        "import physrover.marl as marl\n"
        "try:\n"
        "    marl.parallel_env(n_rovers=3)\n"
        "except ImportError as e:\n"
        "    print(e)\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == MISSING_PETTINGZOO
