"""The whole-episode compiled rollout plays exactly what the step-by-step world plays.

:func:`physrover.learn.rollout.policy_episode` composes the world's own step with the
policies' forward pass; these tests play the same teams both ways (the compiled episode,
and ``world.step`` called once per step on the same :class:`TeamPolicy`) and compare every
record bit for bit, then whole CCEA generations of every fitness method both ways; and
check :func:`physrover.learn.forward.tanh32` against float64 tanh.
"""

import numpy as np
import pytest

from physrover import RoverVectorEnv
from physrover.config import DomainConfig, RunConfig
from physrover.core.registry import FITNESS_METHODS
from physrover.domain.world import RoverWorld
from physrover.learn.ccea import CCEA
from physrover.learn.forward import policy_forward, tanh32
from physrover.learn.policies import PolicyLayout
from physrover.learn.rollout import TeamPolicy, play_episode

RECORDS = ("observations", "actions", "position_history")


def _teams(config: DomainConfig, n_teams: int, seed: int, scale: float = 1.0) -> TeamPolicy:
    world = RoverWorld(config, n_teams)
    layout = PolicyLayout(7, world.obs_dim)
    genomes = layout.init((n_teams, config.n_rovers), np.random.default_rng(seed)) * scale
    return layout.prepare(genomes)


def _play(config, policy, seed, compiled, headings=True):
    world = RoverWorld(config, policy.genomes.shape[0])
    rngs = [np.random.default_rng([seed, e]) for e in range(world.n_teams)]
    obs = world.reset(rngs)
    if compiled:
        assert world.compiled
        play_episode(world, obs, policy, headings)
    else:
        for _ in range(config.steps):
            obs = world.step(policy(obs))
    return world


@pytest.mark.parametrize(
    "fields",
    [
        {},  # the paper's domain
        {"n_req": 1, "n_rovers": 4, "steps": 30, "scored_states": "before-steps", "d_cap": 12.0},
        {
            "sensor.sectors": 6,
            "sensor.radius": 5.0,
            "poi_values": [1.0, 2.0, 3.0],
        },  # the general sensor loop
        {"sensor.radius": 3.0, "n_rovers": 19},  # radius in the quadrant loop, 2 pads
    ],
)
def test_the_compiled_episode_is_the_step_loop_bit_for_bit(fields):
    config = DomainConfig().replace(**fields)
    # large weights: saturated commands, crowds near POIs, captures and their absence
    policy = _teams(config, 9, seed=3, scale=4.0)
    fused = _play(config, policy, 11, compiled=True)
    stepped = _play(config, policy, 11, compiled=False)
    assert fused.t == stepped.t == config.steps
    for name in RECORDS + ("heading_history",):
        np.testing.assert_array_equal(getattr(fused, name), getattr(stepped, name), err_msg=name)
    for name, a in fused.state._asdict().items():
        np.testing.assert_array_equal(a, getattr(stepped.state, name), err_msg=name)
    assert np.array_equal(fused.G, stepped.G) and np.array_equal(fused.D, stepped.D)
    if fields.get("n_req") == 1:  # the test saw captures and their absence
        assert (
            0 < np.count_nonzero(fused.G) and fused.state.captured.sum() < fused.state.captured.size
        )


def test_without_headings_only_the_angles_are_left_out():
    config = DomainConfig()
    policy = _teams(config, 5, seed=1)
    fast = _play(config, policy, 2, compiled=True, headings=False)
    full = _play(config, policy, 2, compiled=True)
    for name in RECORDS:
        np.testing.assert_array_equal(getattr(fast, name), getattr(full, name))
    np.testing.assert_array_equal(fast.state.cos_h, full.state.cos_h)
    assert np.array_equal(fast.D, full.D)
    assert np.isnan(fast.heading_history[1:]).all() and np.isnan(fast.rover_headings).all()
    np.testing.assert_array_equal(fast.heading_history[0], full.heading_history[0])


def test_physical_motion_plays_the_step_loop():
    config = DomainConfig().replace(motion="physics", n_rovers=4, steps=8, n_req=2)
    policy = _teams(config, 3, seed=5)
    world = RoverWorld(config, 3)
    assert not world.compiled
    play_episode(world, world.reset([np.random.default_rng([7, e]) for e in range(3)]), policy)
    stepped = _play(config, policy, 7, compiled=False)
    assert world.t == config.steps
    for name in RECORDS + ("heading_history",):
        np.testing.assert_array_equal(getattr(world, name), getattr(stepped, name))
    assert np.ptp(world.position_history[:, 0, 0, 0]) > 0  # the rovers moved


def test_bad_teams_are_clear_errors():
    config = DomainConfig()
    policy = _teams(config, 4, seed=0)
    world = RoverWorld(config, 3)
    obs = world.reset([np.random.default_rng(e) for e in range(3)])
    with pytest.raises(ValueError, match="3 teams of 15 rovers"):
        play_episode(world, obs, policy)
    world.step(np.zeros((3, 15, 2)))
    with pytest.raises(RuntimeError, match="reset world"):
        play_episode(world, obs, _teams(config, 3, seed=0))
    genomes = _teams(config, 3, seed=0).genomes.copy()
    genomes[1, 2, :] = np.nan
    world = RoverWorld(config, 3)
    obs = world.reset([np.random.default_rng(e) for e in range(3)])
    with pytest.raises(ValueError, match="NaN"):
        play_episode(world, obs, TeamPolicy(genomes, 7, 8))
    assert world.t == 0  # left mid-episode, not done
    env = RoverVectorEnv(3)
    env.reset(seed=0)
    with pytest.raises(ValueError, match="NaN"):
        env.play_episode(TeamPolicy(genomes, 7, 8))
    _, rewards, *_ = env.step(np.zeros((3, 15, 2)))  # the next step resets, as after an end
    assert env.world.t == 0 and not rewards.any()


@pytest.mark.parametrize("method", list(FITNESS_METHODS))
def test_every_method_trains_the_same_with_the_compiled_episode(method, monkeypatch):
    """Generations of the CCEA with the compiled episode and with the step loop: the same
    genomes, fitness, champions and metrics, bit for bit."""
    config = RunConfig().with_overrides(
        {
            "method": method,
            "n_rovers": 5,
            "n_req": 2,
            "poi_values": [1.0, 2.0, 3.0],
            "population": 6,
            "steps": 20,
            "eval_episodes": 3,
            "seed": 4,
            "d_cap": 8.0,
        }  # fmt: skip
    )
    if method in ("average", "leniency"):
        config = config.with_overrides({"n_samples": 3})
    fast = CCEA(config)
    fast_stats = [fast.run_generation() for _ in range(3)]
    monkeypatch.setattr(RoverWorld, "compiled", property(lambda self: False))
    slow = CCEA(config)
    slow_stats = [slow.run_generation() for _ in range(3)]
    for a, b in zip(fast_stats, slow_stats, strict=True):
        assert (a.eval_G, a.train_G_mean, a.fitness_mean) == (b.eval_G, b.train_G_mean,
                                                              b.fitness_mean)  # fmt: skip
        assert a.critic_loss == b.critic_loss or (np.isnan(a.critic_loss)
                                                  and np.isnan(b.critic_loss))  # fmt: skip
    np.testing.assert_array_equal(fast.genomes, slow.genomes)
    np.testing.assert_array_equal(fast.fitness, slow.fitness)
    np.testing.assert_array_equal(fast.champion, slow.champion)


def test_tanh32_is_float64_tanh_rounded_once():
    rng = np.random.default_rng(0)
    x = np.concatenate([
        rng.normal(0.0, 2.0, 200_000), rng.uniform(-12.0, 12.0, 200_000),
        rng.normal(0.0, 1e-3, 100_000),
        np.ldexp(rng.uniform(-1.0, 1.0, 100_000), rng.integers(-149, 0, 100_000)),
        [0.0, 1e-45, 2.0**-12, 0.34657359, 0.5, 9.01, 10.0, 10.5, 88.0, 3.4e38, np.inf],
    ]).astype(np.float32)  # fmt: skip
    x = np.concatenate([x, -x])
    want = np.tanh(x.astype(np.float64)).astype(np.float32)
    scalar = np.array([tanh32(v) for v in x[::300]], dtype=np.float32)  # one call at a time
    np.testing.assert_array_equal(scalar, want[::300])
    np.testing.assert_array_equal(_tanh_all(x), want)  # the vectorised loop of the policy
    assert np.signbit(tanh32(np.float32(-0.0))) and not np.signbit(tanh32(np.float32(0.0)))
    assert np.isnan(tanh32(np.float32(np.nan)))
    assert tanh32(np.float32(-np.inf)) == -1.0


def _tanh_all(x: np.ndarray) -> np.ndarray:
    """tanh32 of every element through the compiled policy: weights making the output
    pre-activations exactly ``x`` (no hidden unit active, b2 = (x, x))."""
    n = len(x)
    layout = PolicyLayout(4, 2)
    genomes = np.zeros((n, 1, layout.size), dtype=np.float32)
    genomes[:, 0, layout.bounds[3]] = x
    genomes[:, 0, layout.bounds[3] + 1] = x
    out = np.empty((n, 1, 2), dtype=np.float32)
    policy_forward(genomes, 4, np.zeros((n, 1, 2), dtype=np.float32), out, (0, 0))
    assert np.array_equal(out[:, 0, 0], out[:, 0, 1], equal_nan=True)
    return out[:, 0, 0]
