"""Trajectory critics: each network against an independent implementation (torch.nn.GRU,
a plain-loop attention), gradients against finite differences, the rank loss against a
plain loop, a trajectory property the paper's max critic cannot represent learned, and a
resumed run bit-identical."""

import numpy as np
import pytest
import torch
from conftest import assert_same_run
from test_learning import EASY

from physrover.config import RunConfig
from physrover.experiment.training import train
from physrover.learn.critics import CriticSettings, FitnessCritic, IntermediateCritics
from physrover.learn.trajectory_critics import (
    TrajectoryCritic,
    TrajectorySettings,
    attention_values,
    gru_values,
    init_params,
    rank_loss,
    recurrent_max_steps,
)


def _settings(model="gru", readout="final", loss="mse", hidden=8, lr=1e-2, batch=16, batches=4):
    return TrajectorySettings(model, readout, loss, hidden, lr, 400, batch, batches)


def _torch_gru_states(p, r, x):
    """torch.nn.GRU with rover r's weights of ``p`` over its (N, T, D) trajectories
    ``x[r]``: the (N, T, H) hidden states h_0 ... h_{T-1}."""
    D, H = p["W_x"].shape[1], p["W_h"].shape[1]
    gru = torch.nn.GRU(D, H, batch_first=True)
    with torch.no_grad():
        gru.weight_ih_l0.copy_(p["W_x"][r].T)
        gru.weight_hh_l0.copy_(p["W_h"][r].T)
        gru.bias_ih_l0.copy_(p["b_x"][r])
        gru.bias_hh_l0.copy_(p["b_h"][r])
        return gru(x[r])[0]


@pytest.mark.parametrize("readout", ["final", "sum"])
def test_the_gru_is_torchs_gru_rover_by_rover(readout):
    rng = np.random.default_rng(0)
    R, N, T, D, H = 3, 5, 7, 4, 6
    p = init_params("gru", R, T, D, H, rng)
    x = torch.from_numpy(rng.normal(size=(R, N, T, D)).astype(np.float32))
    ours = gru_values(p, x, readout)
    for r in range(R):
        states = _torch_gru_states(p, r, x)  # (N, T, H)
        per_step = states @ p["w"][r] + p["b"][r]  # (N, T, 1)
        expected = per_step[:, -1, 0] if readout == "final" else per_step[..., 0].sum(-1)
        torch.testing.assert_close(ours[r], expected, rtol=1e-5, atol=1e-5)


def test_recurrent_max_is_the_papers_critic_on_the_pair_and_the_gru_before_it():
    rng = np.random.default_rng(5)
    R, N, T, D, H, U = 2, 3, 6, 4, 5, 7
    p = init_params("recurrent-max", R, T, D, H, rng, units=U)
    p["b2"] += torch.tensor([[0.3], [-0.2]])
    x = torch.from_numpy(rng.normal(size=(R, N, T, D)).astype(np.float32))
    ours = recurrent_max_steps(p, x, 0.01)  # (R, N, T)
    for r in range(R):
        states = _torch_gru_states(p, r, x)
        for n in range(N):
            for t in range(T):
                before = states[n, t - 1] if t else torch.zeros(H)
                z = torch.cat([x[r, n, t], before]).double().numpy()
                pre = z @ p["W1"][r].double().numpy() + p["b1"][r].double().numpy()
                value = np.where(pre > 0, pre, 0.01 * pre).sum() + float(p["b2"][r, 0])
                assert float(ours[r, n, t]) == pytest.approx(value, rel=1e-4, abs=1e-4)
    # A GRU that always outputs 0 leaves the paper's critic (Eq. 2) on the pair alone.
    for name in ("W_x", "b_x", "W_h", "b_h"):
        p[name].zero_()
    paper = IntermediateCritics(R, D, U, 0.01, rng)
    paper.W1[...] = p["W1"][:, :D].numpy()
    paper.b1[...] = p["b1"].numpy()
    paper.b2[...] = p["b2"][:, 0].numpy()
    expected = paper(x.reshape(R, N * T, D).numpy()).reshape(R, N, T)
    np.testing.assert_allclose(recurrent_max_steps(p, x, 0.01).numpy(), expected, rtol=1e-5,
                               atol=1e-5)  # fmt: skip


def test_the_attention_critic_is_its_plain_loop():
    rng = np.random.default_rng(1)
    R, N, T, D, H = 2, 3, 5, 4, 6
    p = init_params("attention", R, T, D, H, rng)
    x = rng.normal(size=(R, N, T, D))
    ours = attention_values(p, torch.from_numpy(x.astype(np.float32))).numpy()
    q = {k: v.numpy().astype(np.float64) for k, v in p.items()}
    for r in range(R):
        for n in range(N):
            e = [np.maximum(x[r, n, t] @ q["W_e"][r] + q["b_e"][r], 0) + q["pos"][r, t]
                 for t in range(T)]  # fmt: skip
            Q = [e_t @ q["W_q"][r] for e_t in e]
            K = [e_t @ q["W_k"][r] for e_t in e]
            V = [e_t @ q["W_v"][r] for e_t in e]
            pooled = np.zeros(H)
            for t in range(T):
                scores = np.array([Q[t] @ K[u] / np.sqrt(H) for u in range(T)])
                weights = np.exp(scores - scores.max()) / np.exp(scores - scores.max()).sum()
                pooled += sum(weights[u] * V[u] for u in range(T)) / T
            hidden = np.maximum(pooled @ q["W_o"][r] + q["b_o"][r], 0)
            expected = hidden @ q["w"][r][:, 0] + q["b"][r][0]
            assert ours[r, n] == pytest.approx(expected, rel=1e-4, abs=1e-5)


@pytest.mark.parametrize("model,readout", [("gru", "final"), ("gru", "sum"),
                                           ("recurrent-max", "max"),
                                           ("attention", "final")])  # fmt: skip
@pytest.mark.parametrize("loss", ["mse", "rank"])
def test_gradients_match_finite_differences(model, readout, loss):
    rng = np.random.default_rng(2)
    R, N, T, D, H = 2, 4, 5, 3, 4
    p = {k: v.double().requires_grad_(True) for k, v in
         init_params(model, R, T, D, H, rng).items()}  # fmt: skip
    x = torch.from_numpy(rng.normal(size=(R, N, T, D)))
    f = torch.from_numpy(rng.permutation(R * N).reshape(R, N).astype(np.float64))

    def objective(*params):
        named = dict(zip(p, params, strict=True))
        if model == "gru":
            values = gru_values(named, x, readout)
        elif model == "recurrent-max":
            values = recurrent_max_steps(named, x, 0.01).amax(-1)
        else:
            values = attention_values(named, x)
        return ((values - f) ** 2).mean() if loss == "mse" else rank_loss(values, f)

    assert torch.autograd.gradcheck(objective, tuple(p.values()), eps=1e-6, atol=1e-5)


def test_the_rank_loss_is_its_plain_loop():
    rng = np.random.default_rng(3)
    values, feedback = rng.normal(size=(3, 6)), rng.integers(0, 3, (3, 6)).astype(float)
    total, pairs = 0.0, 0
    for r in range(3):
        for k in range(6):
            for m in range(6):
                if feedback[r, k] > feedback[r, m]:
                    total += np.log1p(np.exp(-(values[r, k] - values[r, m])))
                    pairs += 1
    ours = rank_loss(torch.from_numpy(values), torch.from_numpy(feedback))
    assert float(ours) == pytest.approx(total / pairs)


def _counting_task(rng, n, T=10):
    """Trajectories of two fixed pairs a and b; the target is how many steps are a's."""
    a, b = np.array([1.0, 0.0, 0.5, 0.0]), np.array([0.0, 1.0, 0.0, 0.5])
    is_a = rng.random((n, T)) < rng.random((n, 1))
    trajectories = np.where(is_a[..., None], a, b).astype(np.float32)
    return trajectories[None], is_a.sum(1).astype(np.float32)[None]  # one rover


def _spearman(x, y):
    rank = lambda v: np.argsort(np.argsort(v))  # noqa: E731
    return np.corrcoef(rank(x), rank(y))[0, 1]


@pytest.mark.parametrize("method", [("gru", "final"), ("gru", "sum"), ("attention", "final")])
def test_a_trajectory_critic_learns_what_the_max_critic_cannot_represent(method):
    """How many steps of the episode were spent at a: a trajectory critic learns to rank
    episodes by it, while every max-aggregated per-pair critic gives the same fitness to
    all episodes that visit both a and b (max_t C(x_t) = max(C(a), C(b)))."""
    rng = np.random.default_rng(4)
    train_x, train_y = _counting_task(rng, 400)
    test_x, test_y = _counting_task(rng, 200)
    critic = TrajectoryCritic(1, 10, 4, _settings(*method, hidden=16, batch=32, batches=1), rng)
    critic.store(train_x, train_y)
    for _ in range(600):
        critic.update(rng)
    fitness = critic.fitness(test_x)[0]
    assert _spearman(fitness, test_y[0]) > 0.9

    paper = FitnessCritic(1, 10, 4, CriticSettings("max", "inexact", 80, 0.01, 1e-3, "adam",
                                                   4000, 50, 50), rng)  # fmt: skip
    both = (test_y[0] > 0) & (test_y[0] < 10)
    assert len(np.unique(paper.fitness(test_x)[0][both])) == 1


def test_seeded_construction_and_updates_repeat():
    def run(seed):
        rng = np.random.default_rng(seed)
        critic = TrajectoryCritic(2, 6, 3, _settings(), rng)
        critic.store(rng.normal(size=(2, 20, 6, 3)).astype(np.float32),
                     rng.normal(size=(2, 20)).astype(np.float32))  # fmt: skip
        critic.update(rng)
        return critic.state()["params"]

    a, b, c = run(0), run(0), run(1)
    assert all(np.array_equal(a[k], b[k]) for k in a)
    assert not np.array_equal(a["W_x"], c["W_x"])


@pytest.mark.parametrize(
    "method", ["gru-critic", "gru-sum-critic", "recurrent-max-critic", "attention-critic"]
)
def test_resume_is_bit_identical(tmp_path, method):
    loss = "rank" if method == "gru-critic" else "mse"
    config = RunConfig().with_overrides({
        **EASY, "method": method, "trajectory_loss": loss, "trajectory_hidden": 8,
        "trajectory_batch": 8, "trajectory_batches": 2, "replay_trajectories": 60,
        "checkpoint_every": 3, "seed": 5,
    })  # fmt: skip
    full = train(config, tmp_path / "full", generations=8, progress=False)
    part = train(config, tmp_path / "part", generations=5, progress=False)
    train(None, part, resume=True, generations=8, progress=False)
    assert_same_run(full, part)


def test_trajectory_fields_are_for_trajectory_critics_only():
    from physrover.config import ConfigError

    with pytest.raises(ConfigError, match="trajectory_loss.*max-critic"):
        RunConfig().with_overrides({"method": "max-critic", "trajectory_loss": "rank"})
    with pytest.raises(ConfigError, match="trajectory_loss"):
        RunConfig().with_overrides({"method": "gru-critic", "trajectory_loss": "hinge"})
