"""Agents that fail mid-episode, as each ecosystem expects: gymnasium's infos, PettingZoo's
``agents`` (an agent leaves when it fails; PettingZoo's own API test), TorchRL's mask
(``check_env_specs``), and the CCEA training teams that lose members."""

import warnings

import numpy as np
import pytest

from physrover import RoverEnv, RoverVectorEnv
from physrover.config import RunConfig
from physrover.learn.ccea import CCEA

FAILING = {"n_rovers": 4, "n_req": 1, "steps": 10, "poi_ring_radius": 4.0,
           "failures": {"given": [[1, 3], [3, 0]], "n_failing": 1, "between": [5, 7]}}  # fmt: skip


def test_gymnasium_infos_say_who_is_alive():
    from gymnasium.utils.env_checker import check_env

    env = RoverEnv(**FAILING)
    check_env(env, skip_render_check=True)
    obs, info = env.reset(seed=3)
    at = env.world.plan.step.failures.at[0]
    assert (info["alive"] == (0 < at)).all() and not info["alive"][3]
    for t in range(1, 11):
        obs, _, _, _, info = env.step(np.ones((4, 2), dtype=np.float32))
        np.testing.assert_array_equal(info["alive"], t < at)
        assert (obs[~info["alive"]] == 0).all()
    vec = RoverVectorEnv(3, **FAILING)
    _, infos = vec.reset(seed=0)
    assert infos["alive"].shape == (3, 4) and infos["_alive"].all()
    assert "alive" not in RoverEnv(n_rovers=4).reset(seed=0)[1]  # off: the keys as before


def test_pettingzoo_agents_leave_when_they_fail(pytestconfig):
    pytest.importorskip("pettingzoo")
    from pettingzoo.test import parallel_api_test

    from physrover.envs.pettingzoo_env import parallel_env

    with warnings.catch_warnings():
        # the API test warns (not fails) where a dict's keys are not the live agents
        warnings.filterwarnings("error", "(Live agent was not given|Agent was given|No agents)")
        parallel_api_test(parallel_env(**FAILING), num_cycles=25)
    env = parallel_env(**FAILING)
    obs, infos = env.reset(seed=1)
    at = env.env.world.plan.step.failures.at[0]
    assert env.agents == env.possible_agents and set(obs) == set(infos) == set(env.agents)
    assert (obs[env.possible_agents[3]] == 0).all()  # out from the start: terminated next
    total = dict.fromkeys(env.possible_agents, 0.0)
    for t in range(1, 11):
        before = list(env.agents)
        obs, rewards, terminated, truncated, _ = env.step(dict.fromkeys(before, [1.0, 0.0]))
        assert set(obs) == set(rewards) == set(terminated) == set(before)
        for agent in before:
            i = env.possible_agents.index(agent)
            assert terminated[agent] == (t >= at[i])  # terminated by the step it fails at
            assert t == 1 or at[i] >= t  # gone after its termination
            total[agent] += rewards[agent]
        assert env.agents == ([] if t == 10 else [a for a in before if not terminated[a]])
    G = env.env.world.G[0]
    for i, agent in enumerate(env.possible_agents):  # G's increases while it was alive
        if at[i] > 0:
            assert total[agent] <= G + 1e-12


def test_torchrl_groups_carry_a_mask_of_live_agents():
    pytest.importorskip("torchrl")
    import torch
    from torchrl.envs.utils import check_env_specs

    from physrover.envs.torchrl_env import RoverTorchEnv

    env = RoverTorchEnv(5, **FAILING)
    check_env_specs(env, seed=0)
    td = env.reset()
    rollout = env.rollout(10, break_when_any_done=False, tensordict=td)
    mask = rollout.get(("next", "rover", "mask"))  # (5, 10, 4): after each step
    at = torch.from_numpy(env.vector_env.world.plan.step.failures.at)
    steps = torch.arange(1, 11).reshape(1, 10, 1)
    assert torch.equal(mask, steps < at[:, None, :])
    obs = rollout.get(("next", "rover", "observation"))
    assert (obs[~mask] == 0).all()
    assert "mask" not in RoverTorchEnv(2, n_rovers=4).reset()["rover"].keys()


def test_the_ccea_trains_a_team_that_loses_members_reproducibly():
    domain = {k: v for k, v in FAILING.items() if k != "failures"}
    fields = {**domain, **FAILING["failures"], "method": "D", "population": 6, "seed": 4}
    runs, worlds = [], []
    for _ in range(2):
        ccea = CCEA(RunConfig().with_overrides(fields))
        runs.append([(s.eval_G, s.fitness_mean) for s in (ccea.run_generation()
                                                          for _ in range(5))])  # fmt: skip
        worlds.append(ccea.env.world)
    assert runs[0] == runs[1]  # from a seed, failures and all
    at = worlds[0].plan.step.failures.at
    assert (at[:, 3] == 0).all() and (worlds[0].D[:, 3] == 0).all()  # out from the start
    assert (at[:, 1] == 3).all() and (at != np.iinfo(np.int64).max).sum(1).min() == 3


def test_a_failed_rover_is_drawn_grey_and_crossed_where_it_stopped():
    from physrover.viz.classes import CROSS, FAILED
    from physrover.viz.render import ROVER_PX, RenderConfig, Transform, rover_rgb, world_state

    render = RenderConfig(width=320, height=320)
    env = RoverEnv(n_rovers=2, n_req=1, steps=5, render_mode="rgb_array", render_config=render,
                   failures={"given": [[1, 2]]})  # fmt: skip
    env.reset(seed=0, options={"rover_positions": [(0.0, 6.0), (0.0, -6.0)]})
    for _ in range(3):
        env.step(np.array([[0.0, 0.0], [0.5, 0.0]]))
    frame = env.render().astype(int)
    tf = Transform.fit_states([world_state(env.world, 0)], env.config, render)
    x0, y0 = np.round(tf(env.world.rover_positions[0, 0])).astype(int)
    x1, y1 = np.round(tf(env.world.rover_positions[0, 1])).astype(int)
    assert np.abs(frame[y0, x0] - rover_rgb(0)).max() <= 2  # alive: its own colour
    off = ROVER_PX // 2 + 1  # beside the cross's centre, on the body
    assert np.abs(frame[y1, x1 + off] - FAILED[::-1]).max() <= 2  # failed: grey
    assert np.abs(frame[y1, x1] - CROSS[::-1]).max() <= 40  # and crossed
    history = env.world.position_history[:4, 0, 1]  # states 0-3: it stopped at state 1
    assert (history[2:] == history[1]).all() and (history[1] != history[0]).any()
