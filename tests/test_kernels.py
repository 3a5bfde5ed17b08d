"""The compiled kernels against the oracles of tests/oracles.py (plain numpy versions of the
same equations): same episodes, same scores, same critic updates, to float32 rounding where
the arithmetic is continuous."""

import numpy as np
import oracles
import pytest

from physrover.config import DomainConfig, RunConfig
from physrover.domain.world import RoverWorld, StartOverrides
from physrover.learn.ccea import CCEA
from physrover.learn.critics import CriticSettings, FitnessCritic, IntermediateCritics


def _episode(config, n_teams=6, seed=0, dtype=np.float64):
    """A world after an episode of random commands (some beyond [-1, 1]), and the commands."""
    world = RoverWorld(config, n_teams)
    world.reset([np.random.default_rng(seed + e) for e in range(n_teams)])
    shape = (config.steps, n_teams, config.n_rovers, 2)
    commands = np.random.default_rng(99).uniform(-1.2, 1.2, shape).astype(dtype)
    commands[3] = 0.0  # a step of zero commands keeps the headings
    for a in commands:
        world.step(a)
    return world, commands


@pytest.mark.parametrize(
    "n_req, dtype, motion",
    [
        (1, np.float64, "ideal"),
        (2, np.float64, "ideal"),
        (3, np.float64, "ideal"),
        (3, np.float32, "ideal"),  # the policies' actions are float32
        (2, np.float64, "physics"),  # pymunk moves, the compiled kernel senses and scores
    ],
)
def test_world_episode_matches_the_oracles(n_req, dtype, motion):
    # A small ring, so that captures and non-zero D happen at every coupling.
    cfg = DomainConfig(n_rovers=9, n_req=n_req, steps=30, motion=motion).replace(
        poi_ring_radius=6.0, spawn_radius=3.0
    )
    world, commands = _episode(cfg, dtype=dtype)
    ref = oracles.replay(world, commands)
    assert ref["G"].max() > 0 and ref["D"].any()
    np.testing.assert_array_equal(world.G, ref["G"])
    np.testing.assert_array_equal(world.D, ref["D"])
    np.testing.assert_array_equal(world.state.capture_step, ref["capture_step"])
    np.testing.assert_array_equal(world.state.captured_without, ref["captured_without"])
    if motion == "ideal":
        np.testing.assert_allclose(world.position_history, ref["positions"], rtol=0, atol=1e-12)
        np.testing.assert_allclose(world.heading_history, ref["headings"], rtol=0, atol=1e-12)
    # Relations are float32 in the oracle, float64 in the kernel.
    np.testing.assert_allclose(world.observations, ref["observations"], rtol=2e-6, atol=1e-7)
    clipped = np.clip(commands, -1.0, 1.0, dtype=np.float64).astype(np.float32)
    np.testing.assert_array_equal(world.actions, clipped)


def test_a_nan_action_changes_nothing():
    cfg = DomainConfig(n_rovers=3, n_req=1, steps=5)
    world = RoverWorld(cfg, 2)
    world.reset([np.random.default_rng(e) for e in range(2)])
    world.step(np.full((2, 3, 2), 0.5, dtype=np.float32))
    before = {
        name: np.copy(getattr(world, name))
        for name in ("rover_positions", "rover_headings", "position_history", "observations")
    }
    t, G = world.t, world.G
    bad = np.full((2, 3, 2), 0.5, dtype=np.float32)
    bad[1, 2, 1] = np.nan  # the last command of the last team: checked before anything moves
    with pytest.raises(ValueError, match="NaN"):
        world.step(bad)
    assert world.t == t
    np.testing.assert_array_equal(world.G, G)
    for name, value in before.items():
        np.testing.assert_array_equal(getattr(world, name), value, err_msg=name)


def test_a_vanishing_move_still_turns_the_rover():
    # A command of 1e-200 to the left: its square underflows, yet the heading becomes the
    # move's direction (+y), and the next forward move goes along it.
    world = RoverWorld(DomainConfig(n_rovers=1, n_req=1, steps=3), 1)
    world.reset(
        [np.random.default_rng(0)], StartOverrides(rover_positions=[(0, 0)], rover_headings=[0])
    )
    world.step(np.array([[[0.0, 1e-200]]]))
    assert world.rover_headings[0, 0] == np.pi / 2
    world.step(np.array([[[1.0, 0.0]]]))
    np.testing.assert_allclose(world.rover_positions[0, 0], [0.0, 1.0], rtol=0, atol=1e-15)


def test_the_state_is_the_last_history_row():
    # The compiled step writes the new state straight into the history rows.
    world, _ = _episode(DomainConfig(n_rovers=4, steps=6))
    np.testing.assert_array_equal(world.rover_positions, world.position_history[world.t])
    np.testing.assert_array_equal(world.rover_headings, world.heading_history[world.t])


def test_the_compiled_move_matches_the_oracle():
    rng = np.random.default_rng(1)
    positions = rng.uniform(-5, 5, (3, 4, 2))
    headings = rng.uniform(-np.pi, np.pi, (3, 4))
    actions = rng.uniform(-1, 1, (3, 4, 2))
    actions[0, 0] = 0.0
    world = RoverWorld(DomainConfig(n_rovers=4, steps=2), 3)
    world.reset(
        [np.random.default_rng(e) for e in range(3)],
        StartOverrides(rover_positions=positions, rover_headings=headings),
    )
    world.step(actions)
    move, expected_headings = oracles.commanded_move(actions, headings)
    np.testing.assert_allclose(world.rover_positions, positions + move, rtol=0, atol=1e-14)
    np.testing.assert_allclose(world.rover_headings, expected_headings, rtol=0, atol=1e-14)
    assert world.rover_headings[0, 0] == headings[0, 0]  # no move, no turn


@pytest.mark.parametrize("pair_dim", [10, 14])  # the paper's sensor, and one of 6 sectors
def test_critic_values_match_the_oracle(pair_dim):
    rng = np.random.default_rng(2)
    settings = CriticSettings("max", "inexact", 20, 0.01, 1e-3, "sgd", 10, 2, 1)
    fast = FitnessCritic(3, 4, pair_dim, settings, np.random.default_rng(0))
    fast.critics.b2[...] = [0.5, -1.0, 2.0]
    ref = oracles.CriticOracle(fast)
    x = rng.normal(size=(3, 37, pair_dim)).astype(np.float32)
    np.testing.assert_allclose(fast.critics(x), ref(x), rtol=1e-5, atol=1e-5)


@pytest.mark.parametrize("optimizer", ["sgd", "adam"])
@pytest.mark.parametrize(
    "aggregation, update, hidden, batch",
    [
        # Inexact batches of 7, 64 and 65 pairs: padded by 57, none and 63 (PAD_PAIRS).
        ("max", "inexact", 80, 7),
        ("max", "inexact", 13, 7),
        ("max", "inexact", 13, 64),
        ("max", "inexact", 13, 65),
        ("mean", "inexact", 13, 7),
        # Regular batches of 7 and 11 trajectories of 6 steps: 42 and 66 pairs.
        ("mean", "regular", 80, 7),
        ("max", "regular", 13, 7),
        ("mean", "regular", 13, 11),
    ],
)
def test_update_kernel_matches_the_oracle(aggregation, update, hidden, batch, optimizer):
    # lr 1e-3: large steps that still converge (at 1e-2 the critics diverge to ~1e4, where
    # float32 rounding of differently ordered sums is amplified past any fair tolerance).
    settings = CriticSettings(aggregation, update, hidden, 0.01, 1e-3, optimizer, 300, batch, 5)
    fast = FitnessCritic(4, 6, 10, settings, np.random.default_rng(0))
    ref = oracles.CriticOracle(fast)
    rng = np.random.default_rng(3)
    for _ in range(3):
        traj = rng.normal(size=(4, 5, 6, 10)).astype(np.float32)
        feedback = rng.normal(size=(4, 5)).astype(np.float32) * 3
        fast.store(traj, feedback)
        # the oracle draws the same mini-batches from the same buffer
        items, fb = fast.buffer.sample(np.random.default_rng(7), settings.batches * batch)
        loss_ref = ref.update_with(items, fb)
        loss_fast = fast.update(np.random.default_rng(7))
        np.testing.assert_allclose(loss_fast, loss_ref, rtol=1e-5)
    before = IntermediateCritics(4, 10, hidden, 0.01, np.random.default_rng(0))
    for got, want, start in zip(
        fast.critics.params(), [ref.W1, ref.b1, ref.b2], before.params(), strict=True
    ):
        assert not np.array_equal(want, start)  # the updates did something ...
        # ... and the same thing, to float32 rounding at the scale of the parameters (the
        # kernel sums in its own order, which depends on the CPU's vector width)
        np.testing.assert_allclose(got, want, rtol=0, atol=1e-5 * np.abs(want).max())


def test_trajectory_gather_picks_each_policys_pairs():
    cfg = RunConfig().with_overrides(
        {"n_rovers": 4, "population": 6, "steps": 5, "method": "max-critic", "eval_episodes": 2}
    )
    ccea = CCEA(cfg)
    order = ccea.method.plan(np.random.default_rng(0), 4, 6)
    team_index = order.transpose(0, 2, 1).reshape(6, 4)
    ccea.rollout(np.concatenate([team_index, team_index[:2]]))
    where = np.argsort(order, axis=-1)[0]
    got = ccea._trajectories(where)
    assert got.shape == (4, 6, 5, 10)
    obs, act = ccea.env.world.trajectories()
    for r in range(4):
        for p in range(6):
            np.testing.assert_array_equal(got[r, p, :, :8], obs[:, where[r, p], r])
            np.testing.assert_array_equal(got[r, p, :, 8:], act[:, where[r, p], r])
