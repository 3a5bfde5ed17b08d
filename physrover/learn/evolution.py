"""Selection and mutation: binary tournament with Cauchy mutation (paper Section 4.2).

The scheme of the paper's lab's code, applied to every rover's population at once:

1. pair the k policies of a population at random (a fresh permutation; with k odd, the
   last policy of the permutation sits out and survives unchanged);
2. in each pair the policy with the higher fitness wins (ties broken at random); the loser
   is replaced by a copy of the winner, whose weights are each mutated with probability
   ``mutation_rate`` by adding a sample of the standard Cauchy distribution (times
   ``mutation_scale``);
3. winners survive unchanged, so the population size is constant and the best policy of
   a population is never lost. Fitness is maximised.

Each population's random draws come from the generator passed in.
"""

from __future__ import annotations

import numpy as np


def tournament_pairs(
    fitness: np.ndarray, rng: np.random.Generator
) -> tuple[np.ndarray, np.ndarray]:
    """Winners and losers of a random pairing of each population.

    Args:
        fitness: (R, k) fitness of each policy (NaN counts as worst).

    Returns:
        winners, losers: (R, k // 2) policy indices.
    """
    n_pop, k = fitness.shape
    order = np.argsort(rng.random((n_pop, k)), axis=1)  # one random permutation per rover
    a, b = order[:, 0 : k - 1 : 2], order[:, 1:k:2]
    fit = np.where(np.isnan(fitness), -np.inf, fitness)
    fa, fb = np.take_along_axis(fit, a, 1), np.take_along_axis(fit, b, 1)
    coin = rng.random(a.shape) < 0.5
    a_wins = (fa > fb) | ((fa == fb) & coin)
    return np.where(a_wins, a, b), np.where(a_wins, b, a)


def evolve(
    genomes: np.ndarray,
    fitness: np.ndarray,
    rng: np.random.Generator,
    mutation_rate: float,
    mutation_scale: float = 1.0,
) -> tuple[np.ndarray, np.ndarray]:
    """One generation of binary tournament + Cauchy mutation, in place.

    Args:
        genomes: (R, k, P) populations; losers are overwritten.
        fitness: (R, k).

    Returns:
        winners, losers: (R, k // 2) indices, as from :func:`tournament_pairs`.
    """
    winners, losers = tournament_pairs(fitness, rng)
    rows = np.arange(genomes.shape[0])[:, None]
    offspring = genomes[rows, winners]  # (R, k // 2, P) copies
    mutate = rng.random(offspring.shape) < mutation_rate
    offspring[mutate] += (mutation_scale * rng.standard_cauchy(int(mutate.sum()))).astype(
        genomes.dtype
    )
    genomes[rows, losers] = offspring
    return winners, losers
