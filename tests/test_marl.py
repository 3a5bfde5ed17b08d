"""The gradient-based MARL baselines (physrover.marl.mappo, physrover.marl.maddpg)."""

from __future__ import annotations

import io
import json
import math

import numpy as np
import pytest
import torch
from torch import nn

from physrover.config import ConfigError, DomainConfig
from physrover.core.registry import CREDITS
from physrover.core.threads import pin_threads
from physrover.domain.scoring.credit import Credit, register_credit
from physrover.envs.gymnasium_env import RoverVectorEnv
from physrover.learn.policies import PolicyLayout
from physrover.marl.common import gae, run_episodes, soft_update
from physrover.marl.maddpg import MADDPG, MADDPGConfig, ReplayBuffer, clip_per_rover, stacked_mlp
from physrover.marl.mappo import MAPPO, MAPPOConfig

pin_threads(1)

# Two POIs close to the start, n_req = 1: an untrained deterministic team (actions ~ 0)
# scores ~0.6, a trained one ~3 (both POIs).
EASY = DomainConfig(
    n_rovers=3, n_req=1, poi_values=(1.0, 2.0), steps=20, scenario={"poi_ring_radius": 5.0}
)
TIMING_KEYS = ("wall_seconds", "env_steps_per_second")


# -- shared pieces ---------------------------------------------------------------------------


def test_gae_equals_plain_loop_from_the_formula():
    gen = torch.Generator().manual_seed(3)
    T, shape, gamma, lam = 9, (4, 3), 0.9, 0.8
    rewards = torch.randn((T, *shape), generator=gen, dtype=torch.float64)
    values = torch.randn((T, *shape), generator=gen, dtype=torch.float64)
    dones = torch.rand((T, *shape), generator=gen) < 0.25
    dones[4, 0, 0] = True  # an episode end inside the batch, at least once
    last_value = torch.randn(shape, generator=gen, dtype=torch.float64)
    advantages, returns = gae(rewards, values, dones, last_value, gamma, lam)

    for i in range(shape[0]):
        for j in range(shape[1]):
            r, v, d = rewards[:, i, j].tolist(), values[:, i, j].tolist(), dones[:, i, j].tolist()
            for t in range(T):
                # A_t = sum_k (gamma lam)^k delta_{t+k}, up to and including the episode's end.
                expected = 0.0
                for k in range(t, T):
                    next_value = last_value[i, j].item() if k == T - 1 else v[k + 1]
                    delta = r[k] + gamma * next_value * (not d[k]) - v[k]
                    expected += (gamma * lam) ** (k - t) * delta
                    if d[k]:
                        break
                assert advantages[t, i, j].item() == pytest.approx(expected, abs=1e-12)
                assert returns[t, i, j].item() == pytest.approx(expected + v[t], abs=1e-12)


def test_soft_update_moves_the_target_by_tau():
    target, source = nn.Linear(2, 2), nn.Linear(2, 2)
    with torch.no_grad():
        target.weight.fill_(4.0)
        target.bias.fill_(-4.0)
        source.weight.copy_(torch.tensor([[0.0, 1.0], [2.0, 3.0]]))
        source.bias.copy_(torch.tensor([8.0, 0.0]))
    soft_update(target, source, 0.25)
    assert torch.equal(target.weight, torch.tensor([[3.0, 3.25], [3.5, 3.75]]))
    assert torch.equal(target.bias, torch.tensor([-1.0, -3.0]))
    assert torch.equal(source.bias, torch.tensor([8.0, 0.0]))  # the source is untouched


def test_replay_buffer_wraps_and_keeps_the_newest():
    buffer = ReplayBuffer(5, {"x": ((2,), torch.float32), "t": ((), torch.int64)})

    def add(values):
        values = torch.tensor(values)
        buffer.add(x=torch.stack([values, -values], 1).float(), t=values)

    add([0, 1, 2])
    assert (buffer.size, buffer.pointer) == (3, 3)
    add([3, 4, 5, 6])  # slots 3, 4, then wraps to 0, 1: 0 and 1 (the oldest) are overwritten
    assert (buffer.size, buffer.pointer) == (5, 2)
    assert buffer.data["t"].tolist() == [5, 6, 2, 3, 4]
    assert buffer.data["x"][:, 1].tolist() == [-5, -6, -2, -3, -4]

    add(list(range(10, 22)))  # longer than the capacity: its last 5 rows, row i at slot
    assert (buffer.size, buffer.pointer) == (5, (2 + 12) % 5)  # (2 + i) % 5 for i = 7..11
    assert buffer.data["t"].tolist() == [18, 19, 20, 21, 17]

    arrays, meta = buffer.state()
    copy = ReplayBuffer(5, {"x": ((2,), torch.float32), "t": ((), torch.int64)})
    copy.load_state(arrays, meta)
    gen_a, gen_b = torch.Generator().manual_seed(1), torch.Generator().manual_seed(1)
    assert torch.equal(buffer.sample(64, gen_a)["t"], copy.sample(64, gen_b)["t"])


def test_replay_buffer_samples_only_filled_rows():
    buffer = ReplayBuffer(100, {"t": ((), torch.int64)})
    buffer.data["t"].fill_(-1)
    buffer.add(t=torch.arange(7))
    drawn = buffer.sample(500, torch.Generator().manual_seed(0))["t"]
    assert set(drawn.tolist()) == set(range(7))


def test_run_episodes_rewards_sum_to_G_and_D():
    env = RoverVectorEnv(6, config=EASY)
    env.reset(seed=5)
    rng = np.random.default_rng(0)
    actions = rng.uniform(-1, 1, (EASY.steps, 6, 3, 2)).astype(np.float32)
    played = run_episodes(env, lambda obs, t: actions[t], "G")
    assert played.obs.shape == (EASY.steps + 1, 6, 3, 8)
    np.testing.assert_allclose(played.rewards.sum(0), np.repeat(played.G[:, None], 3, 1))
    assert played.G.max() > 0  # the check above is not 0 == 0

    env.reset(seed=5)
    credited = run_episodes(env, lambda obs, t: actions[t], "D")
    np.testing.assert_array_equal(credited.G, played.G)
    assert not credited.rewards[:-1].any()
    np.testing.assert_allclose(credited.rewards[-1], env.world.D)


def test_stacked_mlp_equals_a_loop_over_rovers():
    gen = torch.Generator().manual_seed(0)
    nets = stacked_mlp(3, [5, 4, 2], nn.ReLU, gen, out_bound=0.5)
    x = torch.randn((7, 3, 5), generator=gen)
    out = nets(x)
    first, _, last = nets
    for r in range(3):
        h = torch.relu(x[:, r] @ first.weight[r] + first.bias[r])
        torch.testing.assert_close(out[:, r], h @ last.weight[r] + last.bias[r])
    assert last.weight.abs().max() <= 0.5 and first.weight.abs().max() <= 1 / math.sqrt(5)


def test_maddpg_actor_i_learns_only_through_critic_i():
    trainer = _maddpg(num_envs=2, seed=1)
    gen = torch.Generator().manual_seed(0)
    obs = torch.rand((16, 3, trainer.n_obs), generator=gen)
    actions = torch.rand((16, 3, 2), generator=gen) * 2 - 1
    joint, pre = trainer._own_actions_from_actors(obs, actions)
    torch.testing.assert_close(pre, trainer.actors(obs))
    for i in range(3):  # row i: rover i's own action from its actor, the others' given
        torch.testing.assert_close(joint[:, i, i], torch.tanh(trainer.actors(obs))[:, i])
        others = [j for j in range(3) if j != i]
        torch.testing.assert_close(joint[:, i, others], actions[:, others])
    q = trainer._q(trainer.critics, obs, joint, torch.zeros(16, dtype=torch.int64))
    q[:, 1].sum().backward()
    grad = trainer.actors[0].weight.grad  # (R, n_obs, hidden)
    assert grad[1].abs().sum() > 0
    assert grad[0].abs().sum() == 0 and grad[2].abs().sum() == 0


def test_maddpg_actor_loss_adds_the_pre_tanh_penalty():
    trainer = _maddpg(num_envs=2, seed=1)
    gen = torch.Generator().manual_seed(3)
    obs = torch.rand((16, 3, trainer.n_obs), generator=gen)
    actions = torch.rand((16, 3, 2), generator=gen) * 2 - 1
    step = torch.zeros(16, dtype=torch.int64)
    joint, pre = trainer._own_actions_from_actors(obs, actions)
    q = trainer._q(trainer.critics, obs, joint, step)
    expected = -q.mean(0).sum() + 1e-3 * (pre**2).mean((0, 2)).sum()
    torch.testing.assert_close(trainer.actor_loss(obs, actions, step), expected)
    # a saturated actor is pulled back: the penalty's gradient shrinks its pre-activations
    with torch.no_grad():
        trainer.actors[-1].bias.fill_(5.0)
    trainer.actors.zero_grad()
    (1e-3 * (trainer.actors(obs) ** 2).mean((0, 2)).sum()).backward()
    assert (trainer.actors[-1].bias.grad > 0).all()


def test_gradients_are_clipped_rover_by_rover_and_tensor_by_tensor():
    w = torch.zeros(3, 4, 2, requires_grad=True)
    b = torch.zeros(3, 2, requires_grad=True)
    w.grad = torch.ones(3, 4, 2) * torch.tensor([0.01, 1.0, 10.0])[:, None, None]
    b.grad = torch.ones(3, 2) * torch.tensor([0.01, 0.1, 10.0])[:, None]
    before = [w.grad.clone(), b.grad.clone()]
    clip_per_rover([w, b], 0.5)
    torch.testing.assert_close(w.grad[0], before[0][0])  # under the limit: untouched
    torch.testing.assert_close(b.grad[:2], before[1][:2])  # rover 1's bias norm 0.14: kept
    torch.testing.assert_close(w.grad[1:].flatten(1).norm(dim=1), torch.full((2,), 0.5))
    torch.testing.assert_close(b.grad[2].norm(), torch.tensor(0.5))
    cosine = (w.grad[2] * before[0][2]).sum() / (w.grad[2].norm() * before[0][2].norm())
    assert cosine > 0.9999  # the direction is kept


def test_maddpg_uniform_warmup_actions():
    trainer = _maddpg(num_envs=4, seed=2, warmup_actions="uniform", warmup_steps=10**6)
    trainer.iteration()
    acted = trainer.buffer.state()[0]["actions"][: trainer.buffer.size]
    assert acted.min() >= -1.0 and acted.max() <= 1.0
    assert abs(acted.std() - 1 / np.sqrt(3)) < 0.05  # uniform, not the near-zero actors


# -- configs ---------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("cls", "field", "value"),
    [
        (MAPPOConfig, "num_envs", 0),
        (MAPPOConfig, "reward", "F"),
        (MAPPOConfig, "lr", 0.0),
        (MAPPOConfig, "gamma", 1.5),
        (MAPPOConfig, "gae_lambda", -0.1),
        (MAPPOConfig, "clip", -0.2),
        (MAPPOConfig, "minibatches", 0),
        (MAPPOConfig, "entropy_coef", -1.0),
        (MAPPOConfig, "centralised_critic", 1),
        (MADDPGConfig, "tau", 0.0),
        (MADDPGConfig, "batch_size", 0),
        (MADDPGConfig, "buffer_capacity", 10),
        (MADDPGConfig, "noise_std", -0.1),
        (MADDPGConfig, "warmup_steps", -1),
        (MADDPGConfig, "eval_episodes", 0),
    ],
)
def test_config_errors_name_the_field(cls, field, value):
    with pytest.raises(ConfigError) as error:
        cls(**{field: value})
    assert error.value.field == field
    assert str(error.value).startswith(f"{field}:")


def test_unknown_config_names_are_errors():
    with pytest.raises(ConfigError, match="clip_range"):
        MAPPOConfig.from_dict({"clip_range": 0.1})


def test_too_many_minibatches_name_the_field():
    with pytest.raises(ConfigError) as error:
        MAPPO(MAPPOConfig(num_envs=2, minibatches=41), EASY)  # 2 x 20 team steps
    assert error.value.field == "minibatches"


# -- the trainers ----------------------------------------------------------------------------


def _mappo(**fields) -> MAPPO:
    return MAPPO(MAPPOConfig(**fields), EASY)


def _maddpg(**fields) -> MADDPG:
    return MADDPG(MADDPGConfig(**fields), EASY)


@pytest.mark.parametrize("make", [_mappo, _maddpg])
def test_policy_genomes_play_like_the_torch_policies(make):
    trainer = make(num_envs=4, seed=2)
    trainer.iteration()  # move off the initial weights
    genomes = trainer.policy_genomes()
    layout = PolicyLayout(trainer.config.hidden, trainer.n_obs)
    assert genomes.shape == (3, layout.size)
    obs = np.random.default_rng(0).uniform(0, 2, (5, 3, trainer.n_obs)).astype(np.float32)
    expected = trainer.act(obs)
    np.testing.assert_allclose(layout.act(np.broadcast_to(genomes, (5, 3, layout.size)), obs),
                               expected, atol=1e-6)  # fmt: skip
    assert np.abs(expected).max() > 1e-3  # not trivially zero


@pytest.mark.parametrize(
    ("make", "fields"), [(_mappo, {}), (_maddpg, {"warmup_steps": 0, "batch_size": 16})]
)
def test_trainers_leave_global_rngs_alone(make, fields):
    torch_state = torch.get_rng_state()
    numpy_state = np.random.get_state()[1].copy()  # noqa: NPY002 (the legacy global RNG)
    trainer = make(num_envs=4, **fields)
    trainer.iteration()
    assert trainer.iterations == 1
    assert torch.equal(torch.get_rng_state(), torch_state)
    np.testing.assert_array_equal(np.random.get_state()[1], numpy_state)  # noqa: NPY002


def test_iteration_counts_and_logging_points():
    trainer = _mappo(num_envs=4, log_every=2, eval_episodes=3)
    first, second = trainer.iteration(), trainer.iteration()
    assert (first["iteration"], first["episodes"], first["env_steps"]) == (1, 4, 80)
    assert (second["iteration"], second["episodes"], second["env_steps"]) == (2, 8, 160)
    assert math.isnan(first["eval_G"]) and 0.0 <= second["eval_G"] <= 3.0
    for key in ("train_G_mean", "policy_loss", "value_loss", "wall_seconds"):
        assert math.isfinite(second[key])
    assert trainer.total_iterations == math.ceil(250_000 / 4)


def test_mappo_learns_the_easy_task():
    """~3 s: 40 iterations of 32 episodes, lr raised from the default 3e-4 for the budget."""
    trainer = _mappo(lr=3e-3, seed=0, log_every=1000)
    before = trainer.evaluate(100, seed=10_000)
    for _ in range(40):
        trainer.iteration()
    after = trainer.evaluate(100, seed=10_000)
    assert before < 1.0
    assert after > 2.4 and after > before + 1.5, (before, after)


def test_ippo_learns_the_easy_task():
    trainer = _mappo(lr=3e-3, seed=0, log_every=1000, centralised_critic=False)
    before = trainer.evaluate(100, seed=10_000)
    for _ in range(40):
        trainer.iteration()
    after = trainer.evaluate(100, seed=10_000)
    assert after > 2.4 and after > before + 1.5, (before, after)


def test_maddpg_learns_the_easy_task():
    """~4 s: 20 iterations of 32 episodes, smaller batch and warm-up, more updates."""
    trainer = _maddpg(seed=0, log_every=1000, batch_size=256, warmup_steps=1000, update_every=20)
    before = trainer.evaluate(100, seed=10_000)
    for _ in range(20):
        trainer.iteration()
    after = trainer.evaluate(100, seed=10_000)
    assert before < 1.0
    assert after > 2.3 and after > before + 1.5, (before, after)


def _round_trip(trainer):
    """state() through the files a run directory holds (npz + JSON)."""
    arrays, meta = trainer.state()
    f = io.BytesIO()
    np.savez(f, **arrays)
    f.seek(0)
    with np.load(f) as data:
        arrays = {k: data[k] for k in data.files}
    return arrays, json.loads(json.dumps(meta))


def _assert_resume_is_bit_identical(make, n: int):
    straight = make()
    for _ in range(n):
        last_straight = straight.iteration()

    first_half = make()
    for _ in range(n // 2):
        first_half.iteration()
    resumed = make()
    resumed.load_state(*_round_trip(first_half))
    for _ in range(n - n // 2):
        last_resumed = resumed.iteration()

    for key in TIMING_KEYS:
        last_straight.pop(key), last_resumed.pop(key)
    assert json.dumps(last_straight) == json.dumps(last_resumed)  # NaN-safe exact equality
    a, b = straight.state()[0], resumed.state()[0]
    assert a.keys() == b.keys()
    for key in a:
        np.testing.assert_array_equal(a[key], b[key], err_msg=key)
    # The streams continue alike: training draws, the env's start states, evaluation.
    assert straight.evaluate() == resumed.evaluate()
    assert json.dumps({k: v for k, v in straight.iteration().items() if k not in TIMING_KEYS}) == (
        json.dumps({k: v for k, v in resumed.iteration().items() if k not in TIMING_KEYS})
    )
    return straight


@pytest.mark.parametrize(("centralised", "reward"), [(True, "G"), (False, "D")])
def test_mappo_resume_is_bit_identical(centralised, reward):
    def make():
        return _mappo(
            num_envs=6, log_every=2, eval_episodes=3, seed=7, lr=3e-3, minibatches=3,
            centralised_critic=centralised, reward=reward,
        )  # fmt: skip

    trainer = _assert_resume_is_bit_identical(make, 6)
    assert "optimizer/agent/0/exp_avg" in trainer.state()[0]  # the moments are compared


def test_maddpg_resume_is_bit_identical():
    def make():
        # 6 x 20 = 120 transitions per iteration: updates start in iteration 2, the
        # 300-slot buffer wraps before the split (after 3 iterations: 360 added), and the
        # transitions not yet paid for by an update carry over it (120 = 2 x 50 + 20).
        return _maddpg(
            num_envs=6, log_every=2, eval_episodes=3, seed=7, batch_size=32,
            buffer_capacity=300, warmup_steps=200, update_every=50,
        )  # fmt: skip

    trainer = _assert_resume_is_bit_identical(make, 6)
    assert trainer.updates > 0 and trainer.buffer.size == 300
    assert "extra/buffer/obs" in trainer.state()[0]


def test_maddpg_updates_clip_both_networks(monkeypatch):
    import physrover.marl.maddpg as module

    seen = []
    real = module.clip_per_rover

    def spy(params, max_norm):
        seen.append((len(params), max_norm))
        real(params, max_norm)

    monkeypatch.setattr(module, "clip_per_rover", spy)
    trainer = _maddpg(num_envs=4, seed=3, warmup_steps=0, batch_size=8, update_every=50)
    trainer.iteration()
    assert trainer.updates > 0 and len(seen) == 2 * trainer.updates
    assert {m for _, m in seen} == {0.5}


# -- one credit vocabulary: any registered signal reaches the trainers -----------------------


class _Tripled(Credit):
    """A user's signal for the tests: three times D."""

    def __call__(self, world):
        return 3.0 * world.D


@pytest.fixture
def tripled():
    register_credit("tripled-D", _Tripled())
    yield "tripled-D"
    del CREDITS._entries["tripled-D"]


@pytest.mark.parametrize("reward", ["D++", "ID", "tripled"])
def test_run_episodes_give_any_registered_credit_at_the_last_step(reward, tripled):
    name = tripled if reward == "tripled" else reward
    crowded = EASY.replace(n_req=2)  # D++ differs from D where a partner was missing
    env = RoverVectorEnv(6, config=crowded)
    env.reset(seed=5)
    actions = np.random.default_rng(0).uniform(-1, 1, (crowded.steps, 6, 3, 2))
    credited = run_episodes(env, lambda obs, t: actions[t].astype(np.float32), name)
    assert not credited.rewards[:-1].any()
    expected = CREDITS[name](env.world)
    np.testing.assert_array_equal(credited.rewards[-1], expected.astype(np.float32))
    if reward == "D++":
        assert (expected != env.world.D).any()  # the check is not D again


@pytest.mark.parametrize("make", [_mappo, _maddpg])
def test_a_trainer_trains_on_the_credit_it_is_given(make, monkeypatch):
    import physrover.marl.maddpg as maddpg
    import physrover.marl.mappo as mappo

    module = mappo if make is _mappo else maddpg
    given = []

    def spy(env, act, reward):
        given.append(reward)
        return run_episodes(env, act, reward)

    monkeypatch.setattr(module, "run_episodes", spy)
    trainer = make(reward="D++", seed=0, log_every=1000)
    trainer.iteration()
    assert given and set(given) == {"D++"}


def test_an_unknown_credit_is_one_line():
    with pytest.raises(ConfigError) as error:
        MAPPOConfig(reward="E")
    assert "reward: unknown credit signal 'E'" in str(error.value)
    assert "\n" not in str(error.value)
