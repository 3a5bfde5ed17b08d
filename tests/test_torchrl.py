"""The native TorchRL env: TorchRL's own spec check, whole multi-episode rollouts with
auto-reset under both motion models, and every step equal to RoverVectorEnv's."""

import numpy as np
import pytest

torch = pytest.importorskip("torch")
pytest.importorskip("torchrl")

from torchrl.envs.utils import check_env_specs  # noqa: E402

from physrover import RoverVectorEnv  # noqa: E402
from physrover.envs.torchrl_env import GROUP, RoverTorchEnv  # noqa: E402

FIELDS = dict(n_rovers=3, n_req=1, steps=8)


@pytest.mark.parametrize("motion", ["ideal", "physics"])
def test_specs_and_a_rollout_of_three_episodes(motion):
    env = RoverTorchEnv(4, motion=motion, **FIELDS)
    check_env_specs(env, seed=0)
    env.set_seed(3)
    rollout = env.rollout(3 * FIELDS["steps"], break_when_any_done=False)
    assert rollout.batch_size == (4, 24)
    n_obs = env.vector_env.single_observation_space.shape[-1]
    assert rollout[GROUP, "observation"].shape == (4, 24, 3, n_obs)
    done = rollout["next", "done"].squeeze(-1)
    assert done[:, 7::8].all() and done.sum() == 4 * 3  # each team ends every 8 steps
    reward = rollout["next", GROUP, "reward"]
    assert (reward == reward[:, :, :1]).all()  # the team reward, the same for every rover


def test_every_step_is_the_vector_envs():
    env, venv = RoverTorchEnv(5, **FIELDS), RoverVectorEnv(5, **FIELDS)
    env.set_seed(11)
    td = env.reset()
    obs, _ = venv.reset(seed=11)
    np.testing.assert_array_equal(td[GROUP, "observation"].numpy(), obs)
    rng = np.random.default_rng(0)
    for _ in range(FIELDS["steps"]):
        action = rng.uniform(-1, 1, (5, 3, 2)).astype(np.float32)
        td[GROUP, "action"] = torch.from_numpy(action)
        out = env.step(td)["next"]
        obs, reward, _, truncated, infos = venv.step(action)
        np.testing.assert_array_equal(out[GROUP, "observation"].numpy(), obs)
        np.testing.assert_array_equal(out[GROUP, "reward"][:, 0, 0].numpy(), reward)
        assert (out["truncated"].squeeze(-1).numpy() == truncated).all()
        d = infos["D"].astype(np.float32)
        np.testing.assert_array_equal(out[GROUP, "info", "D"].numpy(), d)
        td = out
    assert truncated.all()  # the last step: D (zeros before) is the world's


@pytest.mark.parametrize("motion", ["ideal", "physics"])
def test_the_pettingzoo_env_under_torchrls_wrapper(motion):
    """TorchRL's own PettingZooWrapper over physrover.parallel_env: its spec check, then
    three whole episodes (it once failed at an episode's last step, where "D" appeared).
    Hand-worked: with d_cap 20 every rover starts within reach of every POI (ring radius
    15, start disc 1.5), and with n_req = n_rovers = 3 each POI needs all three, so each
    episode's rewards sum to G = 1 + 2 + 3 + 4 = 10 and every rover's D (Eq. 1) is 10,
    reported at the episode's last step only."""
    pytest.importorskip("pettingzoo")
    from torchrl.envs import PettingZooWrapper

    from physrover import parallel_env

    env = PettingZooWrapper(parallel_env(motion=motion, n_rovers=3, n_req=3, d_cap=20.0,
                                         steps=8), use_mask=True, seed=0)  # fmt: skip
    check_env_specs(env, seed=0)
    rollout = env.rollout(24, break_when_any_done=False)
    (group,) = env.group_map  # one group of the three rovers
    assert rollout["next", group, "observation"].shape[:2] == (24, 3)
    reward = rollout["next", group, "reward"][..., 0].numpy()  # (24, 3)
    d = rollout["next", group, "info", "D"].numpy()
    done = rollout["next", "done"].squeeze(-1).numpy()
    assert done[7::8].all() and done.sum() == 3
    for episode in range(3):
        steps = slice(8 * episode, 8 * episode + 8)
        np.testing.assert_allclose(reward[steps].sum(axis=0), [10.0] * 3)
        assert (d[steps][:-1] == 0).all()
        np.testing.assert_allclose(d[steps][-1], [10.0] * 3)
