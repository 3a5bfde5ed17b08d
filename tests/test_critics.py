"""Fitness critics: gradients of Eqs. 7 and 9 against finite differences, aggregation, replay.

The gradient formula is checked on the numpy oracle (tests/oracles.py) in float64; the
compiled update kernel is checked against that oracle in test_kernels.py."""

import numpy as np
import oracles
import pytest

from physrover.config import ConfigError, RunConfig
from physrover.core.compiled import dims
from physrover.learn.configs import CriticConfig
from physrover.learn.critics import (
    CriticSettings,
    FitnessCritic,
    IntermediateCritics,
    ReplayBuffer,
    aggregate,
)
from physrover.learn.kernels import critic_update


def _critic(aggregation, update, hidden=6, seed=0):
    """The numpy oracle of a FitnessCritic, in float64 for the finite differences."""
    settings = CriticSettings(aggregation, update, hidden, 0.01, 1e-3, "sgd", 100, 4, 3)
    oracle = oracles.CriticOracle(FitnessCritic(2, 5, 10, settings, np.random.default_rng(seed)))
    oracle.W1, oracle.b1, oracle.b2 = (
        p.astype(np.float64) for p in (oracle.W1, oracle.b1, oracle.b2)
    )
    oracle.b2 += 0.3
    return oracle


def _params(oracle):
    return [oracle.W1, oracle.b1, oracle.b2]


def _half_squared_error(fc, items, feedback):
    delta, _ = fc.errors_and_directions(items, feedback)
    return 0.5 * (delta**2).sum()


@pytest.mark.parametrize(
    ("aggregation", "update"),
    [("mean", "regular"), ("max", "regular"), ("max", "inexact"), ("mean", "inexact")],
)
def test_update_direction_is_minus_the_gradient_of_half_squared_error(aggregation, update):
    # Eq. 7 (regular) / Eq. 9 (inexact): sum_k delta_k grad F (or grad C) = -dL/dw with
    # L = 1/2 sum_k delta_k^2, per critic. Checked by central differences.
    fc = _critic(aggregation, update)
    rng = np.random.default_rng(1)
    shape = (2, 4, 5, 10) if update == "regular" else (2, 4, 10)
    items = rng.normal(size=shape)
    feedback = rng.normal(size=(2, 4)) * 3
    _, directions = fc.errors_and_directions(items, feedback)
    eps = 1e-6
    for param, direction in zip(_params(fc), directions, strict=True):
        flat = param.reshape(-1)
        numeric = np.zeros_like(flat)
        for j in range(flat.size):
            keep = flat[j]
            flat[j] = keep + eps
            up = _half_squared_error(fc, items, feedback)
            flat[j] = keep - eps
            down = _half_squared_error(fc, items, feedback)
            flat[j] = keep
            numeric[j] = -(up - down) / (2 * eps)
        np.testing.assert_allclose(direction.reshape(-1), numeric, rtol=1e-5, atol=1e-7)


def test_output_weights_are_fixed_to_one():
    # C(x) = sum_h lrelu(z_h) + b2 before and after updates: the hidden-to-output weights are
    # not parameters at all, and only W1, b1, b2 change.
    settings = CriticSettings("max", "inexact", 6, 0.01, 1e-3, "sgd", 100, 4, 3)
    fc = FitnessCritic(2, 5, 10, settings, np.random.default_rng(0))
    rng = np.random.default_rng(2)
    fc.store(rng.normal(size=(2, 4, 5, 10)), rng.normal(size=(2, 4)))
    before = [p.copy() for p in fc.critics.params()]
    fc.update(rng)
    assert all(not np.array_equal(a, b) for a, b in zip(before, fc.critics.params(), strict=True))
    c, x = fc.critics, rng.normal(size=(2, 7, 10))
    z = x @ c.W1 + c.b1[:, None, :]
    expected = np.where(z > 0, z, 0.01 * z).sum(-1) + c.b2[:, None]
    np.testing.assert_allclose(c(x), expected, rtol=1e-6)


def test_max_aggregation_credits_only_the_argmax_pair():
    fc = _critic("max", "regular")
    rng = np.random.default_rng(3)
    traj = rng.normal(size=(2, 1, 5, 10))
    feedback = np.array([[2.0], [-1.0]])
    delta, directions = fc.errors_and_directions(traj, feedback)
    values = fc(traj[:, 0])  # (2, 5)
    best = values.argmax(1)
    only = np.zeros((2, 5))
    only[np.arange(2), best] = delta[:, 0]
    expected = fc.weighted_grad(traj[:, 0], only)
    for got, want in zip(directions, expected, strict=True):
        np.testing.assert_allclose(got, want, rtol=1e-12)
    np.testing.assert_allclose(delta[:, 0], feedback[:, 0] - values.max(1))


def test_aggregate_values_and_weights():
    v = np.array([[1.0, 5.0, 3.0]])
    assert aggregate(v, "max")[0][0] == 5.0
    np.testing.assert_array_equal(aggregate(v, "max")[1], [[0, 1, 0]])
    assert aggregate(v, "mean")[0][0] == 3.0
    np.testing.assert_allclose(aggregate(v, "mean")[1], [[1 / 3] * 3])


def test_intermediate_critic_hand_value():
    c = IntermediateCritics(1, 10, 2, 0.01, np.random.default_rng(0))
    c.W1[...] = 0.0
    c.W1[0, 0] = [1.0, -1.0]  # z = (x0 + 0.5, -x0 - 0.5)
    c.b1[...] = [0.5, -0.5]
    c.b2[...] = 2.0
    x = np.zeros((1, 1, 10), dtype=np.float32)
    x[0, 0, 0] = 1.5  # z = (2, -2) -> lrelu: 2 and -0.02 -> C = 2 - 0.02 + 2
    assert c(x)[0, 0] == pytest.approx(3.98, abs=1e-6)


def test_replay_buffer_keeps_the_newest_entries():
    buf = ReplayBuffer(2, capacity=5, item_shape=(1,))
    for start in (0, 3, 6):  # 9 entries into 5 slots
        items = np.arange(start, start + 3, dtype=np.float32).reshape(1, 3, 1).repeat(2, 0)
        buf.add(items, items[..., 0] * 10)
    assert buf.size == 5
    assert sorted(buf.items[0, :, 0]) == [4, 5, 6, 7, 8]
    np.testing.assert_array_equal(buf.feedback[1], buf.items[1, :, 0] * 10)
    big = np.arange(12, dtype=np.float32).reshape(1, 12, 1).repeat(2, 0)
    buf.add(big, big[..., 0])
    assert sorted(buf.items[0, :, 0]) == [7, 8, 9, 10, 11]
    items, fb = buf.sample(np.random.default_rng(0), 1000)
    assert set(items[0, :, 0]) == {7, 8, 9, 10, 11}
    np.testing.assert_array_equal(fb, items[..., 0])


def test_paper_capacities_hold_ten_generations():
    # k = 50 policies x 50 steps: regular stores 50 trajectories, inexact 2500 pairs per
    # generation; the paper's capacities (500, 25000) keep the last 10 generations.
    from physrover.config import RunConfig
    from physrover.learn.fitness import Problem, make_method

    method = make_method(RunConfig(), Problem(2, 50, 8, 2), np.random.default_rng(0))
    traj = np.zeros((2, 50, 50, 10), dtype=np.float32)
    for g in range(12):
        traj[...] = g
        method.critic.store(traj, np.full((2, 50), float(g)))
    assert method.critic.buffer.size == 25000
    assert sorted(set(method.critic.buffer.feedback[0])) == list(range(2, 12))


def test_a_zero_learning_rate_freezes_the_critic():
    # critic_lr = 0 (the frozen-critic ablation): updates run, report a loss, change nothing
    for optimizer in ("sgd", "adam"):
        settings = CriticSettings("max", "inexact", 6, 0.01, 0.0, optimizer, 100, 4, 3)
        fc = FitnessCritic(2, 5, 10, settings, np.random.default_rng(0))
        rng = np.random.default_rng(4)
        fc.store(rng.normal(size=(2, 4, 5, 10)), rng.normal(size=(2, 4)))
        before = [p.copy() for p in fc.critics.params()]
        assert np.isfinite(fc.update(rng))
        for a, b in zip(before, fc.critics.params(), strict=True):
            np.testing.assert_array_equal(a, b)


def test_step_input_appends_the_step_to_every_pair():
    import dataclasses as dc

    from physrover.learn.critics import CriticSettings, FitnessCritic

    settings = CriticSettings("max", "inexact", 4, 0.01, 1e-3, "sgd", 100, 5, 2)
    rng = np.random.default_rng(0)
    plain = FitnessCritic(2, 3, 10, settings, rng)
    timed = FitnessCritic(2, 3, 10, dc.replace(settings, step_input=True), rng)
    assert (plain.pair_dim, timed.pair_dim) == (10, 11)
    trajectories = rng.uniform(-1, 1, (2, 5, 3, 10)).astype(np.float32)  # (R, k, T, D)
    x = timed.inputs(trajectories)
    assert x.shape == (2, 5, 3, 11) and x.dtype == np.float32
    np.testing.assert_array_equal(x[..., :10], trajectories)
    np.testing.assert_array_equal(x[0, 0, :, 10], [0.0, 0.5, 1.0])  # t / (T - 1)
    assert plain.inputs(trajectories) is trajectories
    # The extra input reaches the critic: its fitness is the max over steps of C(s, a, t).
    values = timed.critics(x.reshape(2, 15, 11)).reshape(2, 5, 3)
    np.testing.assert_array_equal(timed.fitness(trajectories), values.max(-1))
    timed.store(trajectories, np.ones((2, 5)))
    assert timed.buffer.size == 15 and timed.update(rng) >= 0.0


def test_top_k_fitness_is_the_mean_of_the_k_largest_values():
    import dataclasses as dc

    import pytest

    from physrover.config import ConfigError
    from physrover.learn.critics import CriticSettings, FitnessCritic

    settings = CriticSettings("max", "inexact", 4, 0.01, 1e-3, "sgd", 100, 5, 2)
    rng = np.random.default_rng(1)
    critic = FitnessCritic(2, 6, 10, dc.replace(settings, top_k=3), rng)
    trajectories = rng.uniform(-1, 1, (2, 4, 6, 10)).astype(np.float32)
    values = critic.critics(trajectories.reshape(2, 24, 10)).reshape(2, 4, 6)
    expected = np.sort(values, axis=-1)[..., -3:].mean(-1)  # plain sort, the 3 largest
    np.testing.assert_allclose(critic.fitness(trajectories), expected, rtol=1e-6)
    critic_1 = FitnessCritic(2, 6, 10, settings, np.random.default_rng(1))
    np.testing.assert_array_equal(critic_1.fitness(trajectories), values.max(-1))
    with pytest.raises(ConfigError, match="critic_top_k: a softer max is for the max critic"):
        RunConfig().with_overrides({"method": "mean-critic", "critic_top_k": 3})
    with pytest.raises(ConfigError, match="critic_top_k: must be >= 1"):
        CriticConfig(critic_top_k=0)


def test_an_ensemble_values_pairs_by_mean_plus_optimism_times_spread():
    settings = CriticSettings("max", "inexact", 6, 0.01, 1e-3, "sgd", 100, 4, 3,
                              ensemble=3, optimism=0.5)  # fmt: skip
    fc = FitnessCritic(2, 5, 10, settings, np.random.default_rng(0))
    c, rng = fc.critics, np.random.default_rng(1)
    assert c.W1.shape[0] == 6  # rover-major: critic r * 3 + k
    traj = rng.normal(size=(2, 4, 5, 10)).astype(np.float32)
    got = fc.fitness(traj)
    for r in range(2):
        for p in range(4):
            x = traj[r, p]  # (T, D): each member as a plain loop of Eq. 2
            members = []
            for k in range(3):
                i = 3 * r + k
                z = x @ c.W1[i] + c.b1[i]
                members.append(np.where(z > 0, z, 0.01 * z).sum(-1) + c.b2[i])
            members = np.array(members)  # (3, T)
            value = members.mean(0) + 0.5 * members.std(0)
            np.testing.assert_allclose(got[r, p], value.max(), rtol=1e-5)
    # each member draws its own mini-batches from its rover's buffer
    fc.store(traj, rng.normal(size=(2, 4)))
    before = c.W1.copy()
    fc.update(np.random.default_rng(3))
    moved = np.abs(c.W1 - before).reshape(6, -1).sum(1)
    assert np.all(moved > 0) and len(set(np.round(moved, 12))) == 6


def test_critics_share_a_buffer_as_if_it_were_copied():
    """critic_update with buffer_of = [0, 0, 1] is critic_update on the copied rows."""
    rng = np.random.default_rng(4)
    hidden, pairs = 5, 10
    W1T = rng.normal(size=(3, hidden, pairs)).astype(np.float32)
    b1 = rng.normal(size=(3, hidden)).astype(np.float32)
    b2 = np.zeros(3, np.float32)
    items = rng.normal(size=(2, 40, 1, pairs)).astype(np.float32)
    feedback = rng.normal(size=(2, 40)).astype(np.float32)
    index = rng.integers(0, 40, (3, 12))
    args = (np.float32(0.01), np.float32(1e-2))
    shared = [a.copy() for a in (W1T, b1, b2)]
    moments = np.zeros((3, 2, hidden * (pairs + 1) + 1), np.float32)
    critic_update(*shared, None, *args, items, feedback, np.array([0, 0, 1]), index, 4, True,
                  False, moments, 0, dims(pairs))  # fmt: skip
    copied = [a.copy() for a in (W1T, b1, b2)]
    rows = np.array([0, 0, 1])
    critic_update(*copied, None, *args, items[rows], feedback[rows], np.arange(3), index, 4, True,
                  False, moments.copy(), 0, dims(pairs))  # fmt: skip
    for a, b in zip(shared, copied, strict=True):
        np.testing.assert_array_equal(a, b)
    assert not np.array_equal(shared[0], W1T)


def test_ensemble_options_are_checked():
    with pytest.raises(ConfigError, match="critic_optimism: an ensemble's spread needs"):
        CriticConfig(critic_optimism=1.0)
    with pytest.raises(ConfigError, match="critic_ensemble: must be >= 1"):
        CriticConfig(critic_ensemble=0)
    assert CriticConfig(critic_ensemble=4, critic_optimism=1.0).critic_ensemble == 4
    for field, value in (("critic_ensemble", 3), ("critic_output_weights", "trained"),
                         ("critic_step_input", True)):  # fmt: skip
        # a setting of the critic given to a method without one names both
        with pytest.raises(ConfigError, match=f"{field}: is a setting of \\[critic\\] "
                           r"\(mean-critic, max-critic.*not of method 'D'"):  # fmt: skip
            RunConfig().with_overrides({"method": "D", field: value})


@pytest.mark.parametrize("use_max, steps", [(True, 1), (True, 5), (False, 5)])
def test_trained_output_weights_step_along_the_gradient(use_max, steps):
    """One SGD mini-batch with trained output weights moves every parameter (W2 included)
    by lr times minus the gradient of half the summed squared error, which a plain float64
    loop computes by central differences (the max over 5 steps: the kernel's gradient sums
    over the maximising pairs alone)."""
    rng = np.random.default_rng(7)
    hidden, width, batch = 4, 3, 6
    W1 = rng.normal(size=(width, hidden))
    b1, W2, b2 = rng.normal(size=hidden), rng.uniform(0.5, 1.5, hidden), 0.3
    items = rng.normal(size=(1, batch, steps, width))
    feedback = rng.normal(size=(1, batch))

    def half_sq_error(W1, b1, W2, b2):
        total = 0.0
        for j in range(batch):
            z = items[0, j] @ W1 + b1  # (T, H)
            c = np.where(z > 0, z, 0.01 * z) @ W2 + b2
            F = c.max() if use_max else c.mean()
            total += 0.5 * (feedback[0, j] - F) ** 2
        return total

    params = [W1, b1, W2, np.array([b2])]
    numeric = []
    for p in params:
        g = np.zeros_like(p)
        for idx in np.ndindex(p.shape):
            keep = p[idx]
            p[idx] = keep + 1e-6
            up = half_sq_error(*params[:3], params[3][0])
            p[idx] = keep - 1e-6
            down = half_sq_error(*params[:3], params[3][0])
            p[idx] = keep
            g[idx] = (up - down) / 2e-6
        numeric.append(g)
    lr = np.float32(1e-4)
    state = [np.ascontiguousarray(W1.T[None], np.float32), b1[None].astype(np.float32),
             np.array([b2], np.float32), W2[None].astype(np.float32)]  # fmt: skip
    before = [a.copy() for a in state]
    moments = np.zeros((1, 2, hidden * (width + 2) + 1), np.float32)
    critic_update(*state, np.float32(0.01), lr, items.astype(np.float32),
                  feedback.astype(np.float32), np.array([0]), np.arange(batch)[None], batch,
                  use_max, False, moments, 0, dims(width))  # fmt: skip
    steps_taken = [(a - b) / lr for a, b in zip(state, before, strict=True)]
    expected = [-numeric[0].T[None], -numeric[1][None], -numeric[3], -numeric[2][None]]
    for got, want in zip(steps_taken, expected, strict=True):
        np.testing.assert_allclose(got, want, rtol=2e-2, atol=2e-3)
    assert np.abs(steps_taken[3]).max() > 1e-2  # the output weights did move


def test_the_trained_critic_starts_as_the_papers():
    fixed = CriticSettings("max", "inexact", 6, 0.01, 1e-3, "sgd", 100, 4, 3)
    trained = CriticSettings("max", "inexact", 6, 0.01, 1e-3, "sgd", 100, 4, 3,
                             output_weights="trained")  # fmt: skip
    a = FitnessCritic(2, 5, 10, fixed, np.random.default_rng(0))
    b = FitnessCritic(2, 5, 10, trained, np.random.default_rng(0))
    traj = np.random.default_rng(1).normal(size=(2, 3, 5, 10)).astype(np.float32)
    np.testing.assert_array_equal(a.fitness(traj), b.fitness(traj))
    assert len(b.critics.params()) == 4 and b.moments.shape[-1] == a.moments.shape[-1] + 6
    with pytest.raises(ConfigError, match="critic_output_weights"):
        CriticConfig(critic_output_weights="learned")
