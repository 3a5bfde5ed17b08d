"""Gymnasium envs: check_env, construction by field name, rewards, vector/single equivalence."""

import warnings

import gymnasium
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import physrover
from physrover import ConfigError, DomainConfig, RoverEnv, RoverVectorEnv


@pytest.mark.parametrize("fields", [{}, {"n_rovers": 4, "poi_values": (1.0, 2.0), "n_req": 3}])
def test_check_env(fields):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # gymnasium warns about the unbounded Box
        check_env(gymnasium.make(physrover.ENV_ID, **fields).unwrapped)


def test_make_takes_fields_or_config():
    env = gymnasium.make(physrover.ENV_ID, n_rovers=4, poi_values=(1.0, 2.0), n_req=3)
    assert env.unwrapped.config == DomainConfig(n_rovers=4, poi_values=(1.0, 2.0), n_req=3)
    assert env.observation_space.shape == (4, 8) and env.action_space.shape == (4, 2)
    cfg = DomainConfig(n_rovers=6, n_req=2)
    assert RoverEnv(config=cfg).config is cfg
    assert RoverEnv(config=cfg, n_req=4).config.n_req == 4
    v = RoverVectorEnv(3, n_rovers=5, n_req=2)
    assert v.config.n_rovers == 5 and v.action_space.shape == (3, 5, 2)
    with pytest.raises(ConfigError, match="n_agents"):
        RoverEnv(n_agents=3)
    with pytest.raises(ConfigError, match="n_req"):
        RoverVectorEnv(2, n_req=20)


def test_rewards_sum_to_G_and_D_arrives_at_the_end():
    env = RoverEnv(n_rovers=3, n_req=1, poi_values=(2.0,), poi_ring_radius=6.0, steps=12)
    obs, info = env.reset(seed=0, options={"rover_headings": np.zeros(3)})
    assert obs.dtype == np.float32 and obs.shape == (3, 8) and info["G"] == 0.0
    total, truncated = 0.0, False
    while not truncated:
        obs, r, terminated, truncated, info = env.step(np.tile([1.0, 0.0], (3, 1)))
        assert not terminated and "D" in info  # every step: zeros until the last
        if not truncated:
            np.testing.assert_array_equal(info["D"], np.zeros(3))
        total += r
    assert info["G"] == 2.0 == total  # the POI at (6, 0) is reached driving along +x
    np.testing.assert_array_equal(info["D"], [0.0, 0.0, 0.0])  # each rover alone suffices


def test_reset_options_shape_errors():
    env = RoverEnv(n_rovers=3)
    with pytest.raises(ValueError, match="rover_headings must have shape"):
        env.reset(seed=0, options={"rover_headings": np.zeros(4)})
    with pytest.raises(ValueError, match="action must have shape"):
        env.reset(seed=0)
        env.step(np.zeros((2, 2)))


def test_vector_team_i_is_single_env_with_seed_plus_i():
    fields = {"n_rovers": 5, "n_req": 2, "poi_ring_radius": 5.0, "steps": 20}
    n, seed = 4, 123
    venv = RoverVectorEnv(n, **fields)
    singles = [RoverEnv(**fields) for _ in range(n)]
    rng = np.random.default_rng(0)
    obs, infos = venv.reset(seed=seed)
    for i, env in enumerate(singles):
        o, info = env.reset(seed=seed + i)
        np.testing.assert_array_equal(obs[i], o)
    total = np.zeros(n)
    for _episode in range(2):  # across an autoreset too
        for _ in range(fields["steps"]):
            act = rng.uniform(-1, 1, (n, 5, 2)).astype(np.float32)
            obs, rew, term, trunc, infos = venv.step(act)
            total += rew
            for i, env in enumerate(singles):
                o, r, te, tr, info = env.step(act[i])
                np.testing.assert_array_equal(obs[i], o)
                assert (rew[i], term[i], trunc[i]) == (r, te, tr)
                assert infos["G"][i] == info["G"]
                np.testing.assert_array_equal(infos["D"][i], info["D"])  # zeros before the end
                assert infos["_D"][i] == tr
        assert trunc.all() and infos["_D"].all()
        # NEXT_STEP autoreset: the next step only resets, like reset() on the singles.
        obs, rew, term, trunc, infos = venv.step(np.zeros((n, 5, 2)))
        assert not trunc.any() and not rew.any()
        for i, env in enumerate(singles):
            np.testing.assert_array_equal(obs[i], env.reset()[0])
    assert total.max() > 0  # the episodes scored something, so rewards were compared


def test_vector_declares_autoreset_mode_and_spaces():
    venv = RoverVectorEnv(3)
    assert venv.metadata["autoreset_mode"] == gymnasium.vector.AutoresetMode.NEXT_STEP
    assert venv.single_observation_space.shape == (15, 8)
    assert venv.observation_space.shape == (3, 15, 8)
    with pytest.raises(RuntimeError, match="reset"):
        venv.step(np.zeros((3, 15, 2)))
    with pytest.raises(ValueError, match="need 3 seeds"):
        venv.reset(seed=[1, 2])
    venv.reset(seed=[5, 6, 7])  # a list of per-team seeds is accepted


def test_play_episode_is_reset_then_steps_without_the_infos():
    from physrover.learn.policies import PolicyLayout

    layout = PolicyLayout(8, 8)
    genomes = layout.init((6, 5), np.random.default_rng(0))  # (E, R, P)
    policy = layout.prepare(genomes)
    a, b = (RoverVectorEnv(6, n_rovers=5, n_req=2, steps=20) for _ in range(2))
    a.reset(seed=3)
    b.reset(seed=3)
    for _ in range(2):  # two episodes: the generators continue alike
        world = a.play_episode(policy)
        obs, _ = b.reset()
        for _ in range(20):
            obs, *_ = b.step(policy(obs))
        for name in ("G", "D", "observations", "actions", "position_history"):
            np.testing.assert_array_equal(getattr(world, name), getattr(b.world, name), name)
    # Like after a last step, the next step autoresets.
    obs, rewards, *_ = a.step(np.zeros((6, 5, 2)))
    assert a.world.t == 0 and not rewards.any()


def test_info_keys_and_shapes_never_change_within_or_across_episodes():
    """TorchRL builds its specs from the first step's infos: a key that appears later (D on
    the last step) had no slot and broke its PettingZoo wrapper (issue 31)."""
    from physrover.envs import parallel_env

    pytest.importorskip("pettingzoo")
    fields = dict(n_rovers=3, n_req=1, steps=4)

    def layout(info):
        return {k: np.shape(v) for k, v in info.items()}

    env, venv, penv = RoverEnv(**fields), RoverVectorEnv(2, **fields), parallel_env(**fields)
    seen = set()
    for seed in (0, 1):  # across resets
        _, info = env.reset(seed=seed)
        _, infos = venv.reset(seed=seed)
        _, pinfos = penv.reset(seed=seed)
        first = (layout(info), layout(infos), {a: layout(i) for a, i in pinfos.items()})
        for _ in range(fields["steps"]):
            _, _, _, _, info = env.step(env.action_space.sample())
            _, _, _, _, infos = venv.step(venv.action_space.sample())
            _, _, _, _, pinfos = penv.step({a: penv.action_space(a).sample() for a in penv.agents})
            now = (layout(info), layout(infos), {a: layout(i) for a, i in pinfos.items()})
            assert now == first
            seen.add(bool(infos["_D"].all()))
        assert infos["_D"].all()  # the last step gives D, masked in
    assert seen == {True, False}
