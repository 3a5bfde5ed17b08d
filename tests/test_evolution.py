"""Binary tournament with Cauchy mutation: selection, copying, mutation statistics."""

import numpy as np
import oracles
import pytest

from physrover.learn.evolution import evolve, tournament_pairs
from physrover.learn.policies import PolicyLayout


def test_pairs_partition_the_population_and_winners_are_fitter():
    rng = np.random.default_rng(0)
    fitness = rng.normal(size=(3, 10))
    winners, losers = tournament_pairs(fitness, rng)
    assert winners.shape == losers.shape == (3, 5)
    for r in range(3):
        assert sorted(np.concatenate([winners[r], losers[r]])) == list(range(10))
        assert np.all(fitness[r, winners[r]] >= fitness[r, losers[r]])


def test_ties_are_broken_at_random_and_nan_never_wins():
    rng = np.random.default_rng(1)
    wins_of_0 = 0
    for _ in range(400):
        w, _ = tournament_pairs(np.zeros((1, 2)), rng)
        wins_of_0 += w[0, 0] == 0
    assert 150 < wins_of_0 < 250
    w, l = tournament_pairs(np.array([[np.nan, -1e9]]), rng)
    assert (w[0, 0], l[0, 0]) == (1, 0)


def test_losers_become_mutated_copies_and_mutation_rate_is_respected():
    rng = np.random.default_rng(2)
    layout = PolicyLayout(32, 8)
    genomes = layout.init((15, 50), rng)
    before = genomes.copy()
    fitness = rng.normal(size=(15, 50))
    best = fitness.argmax(1)
    winners, losers = evolve(genomes, fitness, rng, mutation_rate=0.01)
    rows = np.arange(15)[:, None]
    np.testing.assert_array_equal(genomes[rows, winners], before[rows, winners])
    np.testing.assert_array_equal(genomes[np.arange(15), best], before[np.arange(15), best])
    changed = genomes[rows, losers] != before[rows, winners]
    # 15 x 25 x 354 = 132750 weights: 1% +- 3 sigma (sigma = 0.027%)
    assert abs(changed.mean() - 0.01) < 0.0009
    jumps = (genomes[rows, losers] - before[rows, winners])[changed]
    # Standard Cauchy: median |x| = 1, and heavy tails (P(|x| > 10) = 6.3%).
    assert 0.85 < np.median(np.abs(jumps)) < 1.15
    assert 0.04 < np.mean(np.abs(jumps) > 10) < 0.09


def test_odd_population_keeps_its_size():
    rng = np.random.default_rng(3)
    genomes = PolicyLayout(4, 8).init((2, 7), rng)
    winners, losers = evolve(genomes, rng.normal(size=(2, 7)), rng, 0.5)
    assert winners.shape == (2, 3) and genomes.shape[1] == 7


@pytest.mark.parametrize("n_in", [8, 12])  # the paper's sensor, and one of 6 sectors
def test_policy_forward_matches_a_plain_loop(n_in):
    rng = np.random.default_rng(4)
    layout = PolicyLayout(5, n_in)
    genomes = layout.init((3, 2), rng)
    obs = rng.random((3, 2, n_in)).astype(np.float32)
    out = layout.act(genomes, obs)
    np.testing.assert_allclose(out, oracles.policy_actions(genomes, 5, obs), rtol=1e-5, atol=1e-6)
    b = layout.bounds
    for e in range(3):
        for r in range(2):
            g = genomes[e, r]
            h = np.maximum(obs[e, r] @ g[b[0] : b[1]].reshape(n_in, 5) + g[b[1] : b[2]], 0)
            expected = np.tanh(h @ g[b[2] : b[3]].reshape(5, 2) + g[b[3] : b[4]])
            np.testing.assert_allclose(out[e, r], expected, rtol=1e-5, atol=1e-6)
    with pytest.raises(ValueError, match=f"{n_in} inputs"):
        layout.act(genomes, obs[..., :-1])
