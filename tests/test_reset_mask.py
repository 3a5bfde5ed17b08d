"""Teams reset apart (issue 44, point 12): ``RoverVectorEnv.reset(options={"reset_mask":
mask})`` as gymnasium's vector API defines it, checked against gymnasium's own
``SyncVectorEnv`` of single ``RoverEnv``s (the oracle: E independent envs, each reset and
autoreset alone); the world's records of a team reset apart against a world of that team
alone; and TorchRL's ``"_reset"`` entry."""

import gymnasium as gym
import numpy as np
import pytest

from physrover.config import DomainConfig
from physrover.domain.world import RoverWorld
from physrover.envs.gymnasium_env import RoverEnv, RoverVectorEnv

PAPER = DomainConfig(n_rovers=4, n_req=2, steps=12, poi_values=(1.0, 2.0, 3.0, 4.0))
MIXED = DomainConfig.from_toml("""
[domain]
n_req = 1
steps = 10
scenario = { kind = "uniform", half_size = 6.0, min_separation = 3.0 }
[[pois]]
value = 1.0
visible_to = ["uav"]
disappear = "captured"
[[pois]]
value = 2.0
after = [0]
[[pois]]
value = 3.0
score_at = "final"
[[agents]]
name = "rover"
count = 3
moves_with = ["uav"]
sensor = { kind = "lidar", radius = 3.0, empty = -1.0, channels = "by-class" }
[[agents]]
name = "uav"
count = 2
captures = false
sensor = { kind = "lidar", radius = 100.0, empty = -1.0, channels = "by-class" }
""")
CONFIGS = {
    "paper": PAPER,
    "physics+collisions": PAPER.replace(motion="physics", collisions=True),
    "mixed team, POI rules": MIXED,
}
E = 3


@pytest.mark.parametrize("name", list(CONFIGS))
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_reset_mask_is_gymnasiums_sync_vector_env_of_single_envs(name, seed):
    config = CONFIGS[name]
    ours = RoverVectorEnv(E, config)
    next_step = gym.vector.AutoresetMode.NEXT_STEP
    oracle = gym.vector.SyncVectorEnv([lambda: RoverEnv(config) for _ in range(E)],
                                      autoreset_mode=next_step)  # fmt: skip
    rng = np.random.default_rng(seed)
    first = [ours.reset(seed=seed)[0], oracle.reset(seed=seed)[0]]
    assert np.array_equal(*first)
    masks = {3: ([False, True, False], None), 8: ([True, False, True], 100 + seed),
             14: ([False, False, True], None)}  # fmt: skip
    for t in range(3 * config.steps):
        if t in masks:
            mask, reseed = np.array(masks[t][0]), masks[t][1]
            (a, info_a), (b, info_b) = (env.reset(seed=reseed, options={"reset_mask": mask})
                                        for env in (ours, oracle))  # fmt: skip
            assert np.array_equal(a, b), t
            assert np.array_equal(info_a["_G"], mask) and np.array_equal(info_b["_G"], mask)
        actions = rng.uniform(-1.0, 1.0, (E, config.n_rovers, 2)).astype(np.float32)
        mine, theirs = ours.step(actions), oracle.step(actions)
        for x, y, what in zip(mine[:4], theirs[:4], ("obs", "reward", "term", "trunc"),
                              strict=True):  # fmt: skip
            assert np.array_equal(x, y), (t, what)
        ended = mine[3]
        if ended.any():  # each team's D on its own last step
            assert np.array_equal(mine[4]["_D"], ended)
            assert np.array_equal(mine[4]["D"][ended], theirs[4]["D"][ended]), t
    assert len(set(ours.world.team_t.tolist())) > 1  # the teams ended apart


@pytest.mark.parametrize("name", list(CONFIGS))
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_a_team_reset_apart_records_what_a_world_of_it_alone_records(name, seed):
    config = CONFIGS[name]
    world, alone, together = (RoverWorld(config, n) for n in (E, 1, E))
    rngs = [np.random.default_rng(10 * seed + s) for s in range(E)]
    twins = [np.random.default_rng(10 * seed + s) for s in range(E)]
    world.reset(rngs)
    together.reset(twins)
    rng = np.random.default_rng(7 + seed)
    actions = rng.uniform(-1.0, 1.0, (config.steps, E, config.n_rovers, 2))
    for t in range(4):
        world.step(actions[t])
        together.step(actions[t])
    mask = np.array([False, True, False])
    copy = np.random.default_rng()
    copy.bit_generator.state = rngs[1].bit_generator.state
    world.reset(rngs, teams=mask)
    alone.reset([copy])
    with pytest.raises(RuntimeError, match="different steps"):
        _ = world.t
    for t in range(config.steps - 4):  # teams 0 and 2 to their ends, team 1 alongside
        world.step(actions[4 + t])
        together.step(actions[4 + t])
        alone.step(actions[4 + t, 1:2])
    assert world.team_t.tolist() == [config.steps, config.steps - 4, config.steps]
    assert world.team_done.tolist() == [True, False, True]
    for a, b in ((world, together), (world, alone)):
        rows = [0, 2] if b is together else [1]
        mine = rows if b is together else [0]
        n = config.steps + 1 if b is together else config.steps - 3
        if b is alone and config.motion == "physics":  # a team's cell in one frame: its
            # positions are offset from another origin than a world of it alone's (1e-15)
            mine_h, alone_h = a.position_history[:n, rows], b.position_history[:n, mine]
            np.testing.assert_allclose(mine_h, alone_h, rtol=0, atol=1e-12)
            continue
        assert np.array_equal(a.position_history[:n, rows], b.position_history[:n, mine])
        assert np.array_equal(a.observations[: n - 1, rows], b.observations[: n - 1, mine])
        assert np.array_equal(a.actions[: n - 1, rows], b.actions[: n - 1, mine])
        assert np.array_equal(a.G[rows], b.G[mine]) and np.array_equal(a.D[rows], b.D[mine])
    with pytest.raises(RuntimeError, match=r"teams \[0, 2\] have no step to take"):
        world.step(actions[0])
    world.step_teams(actions[0], ~world.team_done)  # team 1 steps alone
    assert world.team_t.tolist() == [config.steps, config.steps - 3, config.steps]
    world.reset(rngs)  # a full reset brings the teams together again
    assert world.t == 0 and world.team_t.tolist() == [0, 0, 0]


@pytest.mark.parametrize(
    ("config", "mask", "error", "message"),
    [
        (
            PAPER.replace(motion="physics", walls=True),
            np.array([True, False, False]),
            ValueError,
            "pymunk",
        ),
        (
            PAPER.replace(scenario={"kind": "ring", "redraw": "generation"}),
            np.array([True, False, False]),
            ValueError,
            "redraw = 'episode' or 'never'",
        ),
        (PAPER, [True, False, False], TypeError, "must be a numpy bool array of shape (3,)"),
        (PAPER, np.array([1, 0, 0]), TypeError, "must be a numpy bool array"),
        (PAPER, np.zeros(3, dtype=bool), ValueError, "at least one True value"),
    ],  # fmt: skip
)
def test_a_reset_mask_it_cannot_honour_is_one_line(config, mask, error, message):
    env = RoverVectorEnv(E, config)
    env.reset(seed=0)
    with pytest.raises(error) as caught:
        env.reset(options={"reset_mask": mask})
    assert message in str(caught.value) and "\n" not in str(caught.value)


def test_torchrl_reset_entry_resets_those_teams_alone():
    pytest.importorskip("torchrl")
    import torch

    from physrover.envs.torchrl_env import GROUP, RoverTorchEnv

    env, oracle = RoverTorchEnv(E, PAPER), RoverVectorEnv(E, PAPER)
    env.set_seed(3)
    td = env.reset()
    oracle.reset(seed=3)
    actions = torch.rand(E, PAPER.n_rovers, 2) * 2 - 1
    td[GROUP, "action"] = actions
    td = env.step(td)["next"]
    oracle.step(actions.numpy())
    mask = np.array([True, False, True])
    td["_reset"] = torch.as_tensor(mask).reshape(E, 1)
    out = env.reset(td)
    expected, _ = oracle.reset(options={"reset_mask": mask})
    assert np.array_equal(out[GROUP, "observation"].numpy(), expected)
    assert env.vector_env.world.team_t.tolist() == [0, 1, 0]
